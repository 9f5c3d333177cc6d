//! Signed-distance primitives (mm; negative inside) the phantom's anatomy is built from.

use glam::{Vec2, Vec3};

/// Approximate signed distance to an axis-aligned ellipsoid (centre c, radii r): exact on the
/// axes, smooth and of the right sign everywhere, within ~10% elsewhere (Quílez's bound).
pub fn ellipsoid(p: Vec3, c: Vec3, r: Vec3) -> f32 {
    let q = p - c;
    let k0 = (q / r).length();
    let k1 = (q / (r * r)).length();
    if k1 == 0.0 {
        -r.min_element()
    } else {
        k0 * (k0 - 1.0) / k1
    }
}

/// Approximate signed distance to an axis-aligned ellipse in a plane (as [`ellipsoid`]).
pub fn ellipse(p: Vec2, c: Vec2, r: Vec2) -> f32 {
    let q = p - c;
    let k0 = (q / r).length();
    let k1 = (q / (r * r)).length();
    if k1 == 0.0 {
        -r.min_element()
    } else {
        k0 * (k0 - 1.0) / k1
    }
}

/// Exact signed distance to a capsule (segment a–b, radius r).
pub fn capsule(p: Vec3, a: Vec3, b: Vec3, r: f32) -> f32 {
    let pa = p - a;
    let ba = b - a;
    let h = (pa.dot(ba) / ba.dot(ba)).clamp(0.0, 1.0);
    (pa - ba * h).length() - r
}

/// Smooth union of two distances, blending over `k` mm (polynomial smooth minimum), so bones
/// flare into their ends instead of meeting at creases.
pub fn smooth_union(a: f32, b: f32, k: f32) -> f32 {
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b * (1.0 - h) + a * h - k * h * (1.0 - h)
}

/// Distance from p to a ray in the xy-plane starting at `origin` along unit `dir`, for points
/// beyond `start` mm along it; infinite before that (used for intermuscular septa).
pub fn ray_xy(p: Vec3, origin: Vec2, dir: Vec2, start: f32) -> f32 {
    let q = Vec2::new(p.x, p.y) - origin;
    let along = q.dot(dir);
    if along < start {
        f32::INFINITY
    } else {
        (q - dir * along).length()
    }
}

/// Coverage of a region with signed distance d by an anti-aliased edge `width` mm wide:
/// 1 inside, 0 outside, linear across the edge.
pub fn coverage(d: f32, width: f32) -> f32 {
    (0.5 - d / width).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ellipsoid_distance_is_exact_on_axes() {
        let c = Vec3::new(1.0, 2.0, 3.0);
        let r = Vec3::new(4.0, 2.0, 1.0);
        assert!((ellipsoid(c + Vec3::new(6.0, 0.0, 0.0), c, r) - 2.0).abs() < 1e-5);
        assert!((ellipsoid(c + Vec3::new(0.0, 1.0, 0.0), c, r) + 1.0).abs() < 1e-5);
        assert!(ellipsoid(c, c, r) < 0.0);
    }

    #[test]
    fn capsule_and_union() {
        let d = capsule(
            Vec3::new(0.0, 3.0, 5.0),
            Vec3::ZERO,
            Vec3::new(0.0, 0.0, 10.0),
            1.0,
        );
        assert!((d - 2.0).abs() < 1e-6);
        assert!(smooth_union(1.0, 2.0, 0.5) <= 1.0);
        assert_eq!(smooth_union(1.0, 5.0, 0.5), 1.0);
    }
}
