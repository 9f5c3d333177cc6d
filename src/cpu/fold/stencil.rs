//! CPU twin of shaders/fold/stencil.wgsl: the jacobian kernel's stencil at one voxel, with
//! det J's gradient, for the fold push's twins.

use crate::cpu::common::det3;
use glam::Vec3;

/// A voxel's displacement in `field` (3 floats per voxel).
pub fn displacement(field: &[f32], v: usize) -> Vec3 {
    Vec3::new(field[3 * v], field[3 * v + 1], field[3 * v + 2])
}

/// The neighbours differenced along one axis, and the factor on their difference.
pub struct Arm {
    pub lo: usize,
    pub hi: usize,
    pub factor: f32,
}

/// The stencil on a grid.
pub struct Stencil {
    dims: [usize; 3],
    /// Rows of d(index)/d(world mm).
    mm_to_index: [Vec3; 3],
}

impl Stencil {
    /// On the grid of `dims` (nx, ny, nz, unused) with the rows `mm_to_index`.
    pub fn new(dims: [u32; 4], mm_to_index: [[f32; 4]; 3]) -> Self {
        Stencil {
            dims: [0, 1, 2].map(|a| dims[a] as usize),
            mm_to_index: mm_to_index.map(|r| Vec3::new(r[0], r[1], r[2])),
        }
    }

    /// The grid's dimensions.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Voxel v's indices.
    pub fn voxel_of(&self, v: usize) -> [usize; 3] {
        let [nx, ny, _] = self.dims;
        [v % nx, v / nx % ny, v / (nx * ny)]
    }

    /// The neighbours differenced along `axis` at voxel v (indices c): central inside,
    /// one-sided on a face (the voxel itself on the other side).
    pub fn arm(&self, c: [usize; 3], v: usize, axis: usize) -> Arm {
        let d = self.dims;
        let stride = [1, d[0], d[0] * d[1]][axis];
        let (has_lo, has_hi) = (c[axis] > 0, c[axis] + 1 < d[axis]);
        Arm {
            lo: if has_lo { v - stride } else { v },
            hi: if has_hi { v + stride } else { v },
            factor: if has_lo && has_hi { 0.5 } else { 1.0 },
        }
    }

    /// The rows of J = I + du/dx of `field` at voxel v (indices c), as the jacobian kernel
    /// forms them.
    fn jacobian_rows(&self, field: &[f32], c: [usize; 3], v: usize) -> [Vec3; 3] {
        let d: [Vec3; 3] = std::array::from_fn(|a| {
            let s = self.arm(c, v, a);
            (displacement(field, s.hi) - displacement(field, s.lo)) * s.factor
        });
        let g = self.mm_to_index;
        [
            g[0] * d[0].x + g[1] * d[1].x + g[2] * d[2].x + Vec3::X,
            g[0] * d[0].y + g[1] * d[1].y + g[2] * d[2].y + Vec3::Y,
            g[0] * d[0].z + g[1] * d[1].z + g[2] * d[2].z + Vec3::Z,
        ]
    }

    /// det J of `field` at v alone.
    pub fn det_at(&self, field: &[f32], c: [usize; 3], v: usize) -> f32 {
        let [r0, r1, r2] = self.jacobian_rows(field, c, v);
        det3(r0, r1, r2)
    }

    /// det J of `field` at v (det3, as the jacobian kernel) and its gradient with respect to
    /// each axis's difference.
    pub fn det_and_gradient(&self, field: &[f32], c: [usize; 3], v: usize) -> (f32, [Vec3; 3]) {
        let [r0, r1, r2] = self.jacobian_rows(field, c, v);
        let g = self.mm_to_index;
        let (c0, c1, c2) = (cross3(r1, r2), cross3(r2, r0), cross3(r0, r1));
        let gradient = g.map(|ga| Vec3::new(dot3(c0, ga), dot3(c1, ga), dot3(c2, ga)));
        (det3(r0, r1, r2), gradient)
    }
}

/// a × b, as stencil.wgsl's cross3.
pub fn cross3(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(
        a.y * b.z - b.y * a.z,
        a.z * b.x - b.z * a.x,
        a.x * b.y - b.x * a.y,
    )
}

/// a · b, as stencil.wgsl's dot3.
pub fn dot3(a: Vec3, b: Vec3) -> f32 {
    a.x * b.x + a.y * b.y + a.z * b.z
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The gradient against finite differences of the determinant, on an oblique, anisotropic
    /// grid, at the centre of a 3³ field with large differences.
    #[test]
    fn determinant_gradient_matches_finite_differences() {
        let rows = [
            [0.8, 0.1, 0.0, 0.0],
            [-0.1, 0.75, 0.05, 0.0],
            [0.0, 0.02, 0.4, 0.0],
        ];
        let stencil = Stencil::new([3, 3, 3, 0], rows);
        let mut field: Vec<f32> = (0..81)
            .map(|k| ((k * 37) % 19) as f32 * 0.13 - 1.1)
            .collect();
        let centre = 13;
        let (_, gradient) = stencil.det_and_gradient(&field, [1, 1, 1], centre);
        let h = 1e-3;
        for (a, stride) in [1, 3, 9].into_iter().enumerate() {
            for (c, &analytic) in gradient[a].to_array().iter().enumerate() {
                // u(hi) enters the difference along axis a with factor 0.5.
                let at = 3 * (centre + stride) + c;
                let det_with = |field: &mut Vec<f32>, s: f32| {
                    let kept = field[at];
                    field[at] = kept + s;
                    let det = stencil.det_and_gradient(field, [1, 1, 1], centre).0;
                    field[at] = kept;
                    det
                };
                let numeric = (det_with(&mut field, h) - det_with(&mut field, -h)) / (2.0 * h);
                let analytic = 0.5 * analytic;
                assert!(
                    (numeric - analytic).abs() < 2e-3,
                    "axis {a}, component {c}: {numeric} vs {analytic}"
                );
            }
        }
    }
}
