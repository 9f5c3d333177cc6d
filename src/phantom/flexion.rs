//! Bending the phantom: a deformation that is invertible by construction and is *not* the
//! linear blend skinning the registration uses, so tests of the skinning initialisation are not
//! circular.
//!
//! Each bone group g (femur, shank, patella) turns about the flexion axis by angle t·θ_g as time
//! t runs from 0 to 1. Every point moves with the velocity
//!
//!   v(x, t) = Σ_g w_g(x, t) · θ_g · a × (x − c)
//!
//! where the weights w_g are Shepard weights (∝ d_g⁻⁴, a partition of unity) of the distance
//! d_g to group g *in its pose at time t* (the distance to the straight-pose bone at
//! R_g(t)⁻¹ x). Inside a bone w = 1 for its own group, so bone points follow their group's
//! rotation exactly and stay inside the moving bone: bones move rigidly. The map is the flow of
//! a Lipschitz velocity field, hence a diffeomorphism — tissue cannot fold — unlike a blend of
//! displacements, which folds at large angles. It is a time-dependent variant of the
//! log-Euclidean polyrigid fusion of Arsigny et al. (stationary weights would let bones drift out
//! of their own rigid region at large angles).
//!
//! The map from a bent point back to the straight pose is obtained by integrating backwards
//! (RK4). Inside a bent bone it is that bone's rigid inverse, exactly; within [`EXACT_MM`] of a
//! bone, where the flow shears fastest, it is integrated at every voxel; farther out it is
//! integrated on a lattice about 2.5 mm apart and interpolated trilinearly, blending into the
//! per-voxel flow over [`BLEND_MM`]. That map *is* the phantom's deformation: the bent image is
//! the anatomy sampled through it, so the truth field is exact for the image, not an
//! approximation of it.

use super::anatomy::{group_distance, GROUPS};
use crate::volume::{Affine, Grid};
use glam::{Mat3, Vec3};
use rayon::prelude::*;

/// Weights ∝ e^(−d/λ)/d: near the bones they behave like 1/d, which spreads the shear between
/// two bones evenly across the gap (a steeper law concentrates it mid-gap, where a voxel grid
/// can no longer resolve it); far away the exponential lets the nearest bone dominate, so the
/// thigh follows the femur and the calf the tibia.
const WEIGHT_FALLOFF_MM: f32 = 15.0;
/// The patella is small: its influence is measured with distances scaled up, so it does not
/// drag the anterior thigh along.
const GROUP_DISTANCE_SCALE: [f32; 3] = [1.0, 1.0, 1.5];
/// Patella rotation as a share of the tibia's: it rides round the femoral trochlea, tied to
/// the tibial tuberosity by the patellar tendon, turning less than the shank.
pub const PATELLA_SHARE: f64 = 0.7;
/// RK4 steps over t ∈ [0, 1] on the lattice, away from the bones: at 120° each step turns the
/// shank 10°, where RK4 is accurate to about 1e-6 of the arc per step.
pub const LATTICE_STEPS: usize = 12;
/// RK4 steps near the bones, where the velocity changes across millimetres: with 12 steps a
/// point just outside the tibia at 90° came back up to 0.13 mm inside it (so it was labelled
/// tibia without moving with it); RK4's error falls with the fourth power of the step.
pub const NEAR_BONE_STEPS: usize = 48;
/// Spacing of the lattice the inverse map is computed on away from the bones (mm).
pub const LATTICE_MM: f64 = 2.5;
/// Within this distance of a bent bone every voxel integrates the flow itself. Interpolating
/// the lattice there blends a bone's motion with that of tissue sliding past it: on the paper
/// grid at 90°, 5% of the femur's voxels moved up to 23 mm although the femur stays. The band
/// is wider than a lattice cell's diagonal (4.3 mm), so no voxel in it interpolates a cell that
/// reaches into a bone.
const EXACT_MM: f32 = 5.0;
/// Beyond [`EXACT_MM`] the per-voxel flow hands over to the lattice smoothly over this width, so
/// the interpolation error (a few tenths of a millimetre near the bones) does not step.
const BLEND_MM: f32 = 5.0;

/// A flexion about an axis: the femur stays, the shank turns by θ, the patella by 0.7 θ.
#[derive(Clone, Debug)]
pub struct Flexion {
    /// A point on the axis (world RAS mm), through the femoral condyles.
    pub axis_point: Vec3,
    /// Unit axis direction; a positive angle swings the foot posteriorly.
    pub axis_direction: Vec3,
    /// Flexion angle (degrees).
    pub degrees: f64,
}

impl Flexion {
    /// The phantom knee's flexion: medio-lateral axis through the centres of the condyles.
    pub fn knee(degrees: f64) -> Self {
        Flexion {
            axis_point: Vec3::new(0.0, -8.0, 22.0),
            // Rotating about −x moves points below the axis towards −y (posterior).
            axis_direction: Vec3::new(-1.0, 0.0, 0.0),
            degrees,
        }
    }

    /// Each group's full rotation angle (radians).
    fn group_angles(&self) -> [f32; 3] {
        let theta = self.degrees.to_radians();
        [0.0, theta as f32, (theta * PATELLA_SHARE) as f32]
    }

    /// The rigid motion of group `g` at t = 1, mapping the straight pose to the bent pose, in
    /// f64: x' = R (x − c) + c.
    pub fn group_matrix(&self, group: usize) -> Affine {
        let angle = self.degrees.to_radians() * [0.0, 1.0, PATELLA_SHARE][group];
        let a = self.axis_direction.as_dvec3();
        let c = self.axis_point.as_dvec3();
        let r = nalgebra::Rotation3::from_axis_angle(
            &nalgebra::Unit::new_normalize(nalgebra::Vector3::new(a.x, a.y, a.z)),
            angle,
        );
        let cv = nalgebra::Vector3::new(c.x, c.y, c.z);
        let t = cv - r * cv;
        let mut m = Affine::identity();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(r.matrix());
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&t);
        m
    }

    /// The rigid motion (4×4, straight → bent) of the group a bone label belongs to.
    pub fn bone_matrix(&self, label: u16) -> Affine {
        let group = GROUPS
            .iter()
            .position(|g| g.contains(&label))
            .expect("every bone label is in a group");
        self.group_matrix(group)
    }

    /// Inverse rotations R_g(t)⁻¹ at t = m / (2·steps), m = 0 ..= 2·steps: every time an RK4
    /// stage of a `steps`-step integration evaluates. Computed once per map and passed to
    /// [`Self::straight_point`], which integrates with that many steps.
    pub fn inverse_rotations(&self, steps: usize) -> Vec<[Mat3; 3]> {
        let angles = self.group_angles();
        (0..=2 * steps)
            .map(|m| {
                let t = m as f32 / (2 * steps) as f32;
                std::array::from_fn(|g| Mat3::from_axis_angle(self.axis_direction, -angles[g] * t))
            })
            .collect()
    }

    fn velocity(&self, x: Vec3, inverse: &[Mat3; 3], angles: &[f32; 3]) -> Vec3 {
        let c = self.axis_point;
        let mut weights = [0.0f32; 3];
        let mut inside = None;
        for g in 0..3 {
            let d = group_distance(g, c + inverse[g] * (x - c)) * GROUP_DISTANCE_SCALE[g];
            if d <= 0.0 {
                inside = Some(g);
                break;
            }
            weights[g] = (-d / WEIGHT_FALLOFF_MM).exp() / d;
        }
        let speed = match inside {
            Some(g) => angles[g],
            None => {
                let total: f32 = weights.iter().sum();
                (0..3).map(|g| weights[g] * angles[g]).sum::<f32>() / total
            }
        };
        self.axis_direction.cross(x - c) * speed
    }

    /// The straight-pose point that flexion carries to the bent point p: integrates the flow
    /// backwards from t = 1 to t = 0 with RK4.
    pub fn straight_point(&self, p: Vec3, inverse: &[[Mat3; 3]]) -> Vec3 {
        let angles = self.group_angles();
        let steps = (inverse.len() - 1) / 2;
        let h = 1.0 / steps as f32;
        let mut x = p;
        for k in 0..steps {
            // Time runs backwards: t = 1 − k h; stage times index into `inverse` in halves.
            let m = 2 * (steps - k);
            let v = |x: Vec3, m: usize| self.velocity(x, &inverse[m], &angles);
            let k1 = v(x, m);
            let k2 = v(x - k1 * (h / 2.0), m - 1);
            let k3 = v(x - k2 * (h / 2.0), m - 1);
            let k4 = v(x - k3 * h, m - 2);
            x -= (k1 + 2.0 * k2 + 2.0 * k3 + k4) * (h / 6.0);
        }
        x
    }

    /// det of the Jacobian of the continuous bent → straight map at p, by central differences
    /// ±`delta` mm. On a voxel grid the finite-difference Jacobian of the sampled map can dip
    /// below zero in the thin joint space where the shank slides past the femur (the shear
    /// there is not resolved by voxels of a few mm); this evaluates the map itself.
    pub fn jacobian_determinant(&self, p: Vec3, delta: f32, inverse: &[[Mat3; 3]]) -> f32 {
        let column = |e: Vec3| {
            (self.straight_point(p + e * delta, inverse)
                - self.straight_point(p - e * delta, inverse))
                / (2.0 * delta)
        };
        Mat3::from_cols(column(Vec3::X), column(Vec3::Y), column(Vec3::Z)).determinant()
    }

    /// The bone group a bent point lies in, and the distance to the nearest bent bone (mm, ≤ 0
    /// inside). Groups are tried in the flow's order, so a point is given to the group whose
    /// velocity the flow gives it.
    fn bent_bone(&self, p: Vec3, at_end: &[Mat3; 3]) -> (Option<usize>, f32) {
        let c = self.axis_point;
        let mut nearest = f32::INFINITY;
        for (g, inverse) in at_end.iter().enumerate() {
            let d = group_distance(g, c + *inverse * (p - c));
            if d <= 0.0 {
                return (Some(g), d);
            }
            nearest = nearest.min(d);
        }
        (None, nearest)
    }

    /// The inverse map (bent → straight) of every voxel of `grid`: rigid inside the bones, the
    /// flow itself near them, the lattice farther out (see the module comment).
    pub fn straight_points(&self, grid: &Grid) -> Vec<Vec3> {
        let spacing = grid.spacing();
        let step: [usize; 3] =
            std::array::from_fn(|a| ((LATTICE_MM / spacing[a]).round() as usize).max(1));
        let ldims: [usize; 3] = std::array::from_fn(|a| (grid.dims[a] - 1).div_ceil(step[a]) + 1);
        let coarse = self.inverse_rotations(LATTICE_STEPS);
        let fine = self.inverse_rotations(NEAR_BONE_STEPS);
        let at_end = &fine[2 * NEAR_BONE_STEPS];
        let world = |ijk: [f64; 3]| {
            let w = grid.voxel_to_world(ijk);
            Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32)
        };
        let lattice: Vec<Vec3> = (0..ldims[0] * ldims[1] * ldims[2])
            .into_par_iter()
            .map(|n| {
                let (i, j, k) = (
                    n % ldims[0],
                    (n / ldims[0]) % ldims[1],
                    n / (ldims[0] * ldims[1]),
                );
                let p = world([
                    (i * step[0]) as f64,
                    (j * step[1]) as f64,
                    (k * step[2]) as f64,
                ]);
                self.straight_point(p, &coarse) - p
            })
            .collect();
        let [nx, ny, nz] = grid.dims;
        let c = self.axis_point;
        (0..nx * ny * nz)
            .into_par_iter()
            .map(|n| {
                let ijk = [n % nx, (n / nx) % ny, n / (nx * ny)];
                let p = world(ijk.map(|v| v as f64));
                let (group, distance) = self.bent_bone(p, at_end);
                if let Some(g) = group {
                    return c + at_end[g] * (p - c);
                }
                if distance < EXACT_MM {
                    return self.straight_point(p, &fine);
                }
                let interpolated = p + interpolate(
                    &lattice,
                    ldims,
                    std::array::from_fn(|a| ijk[a] as f32 / step[a] as f32),
                );
                let s = ((distance - EXACT_MM) / BLEND_MM).min(1.0);
                if s >= 1.0 {
                    return interpolated;
                }
                let to_lattice = s * s * (3.0 - 2.0 * s);
                // The lattice's own step count: the blend joins two integrations of one accuracy.
                self.straight_point(p, &coarse)
                    .lerp(interpolated, to_lattice)
            })
            .collect()
    }
}

/// Trilinear interpolation of a lattice of vectors at continuous lattice coordinate l.
fn interpolate(lattice: &[Vec3], dims: [usize; 3], l: [f32; 3]) -> Vec3 {
    let i0: [usize; 3] = std::array::from_fn(|a| (l[a].floor() as usize).min(dims[a] - 1));
    let i1: [usize; 3] = std::array::from_fn(|a| (i0[a] + 1).min(dims[a] - 1));
    let t: [f32; 3] = std::array::from_fn(|a| l[a] - i0[a] as f32);
    let at = |i: usize, j: usize, k: usize| lattice[i + dims[0] * (j + dims[1] * k)];
    let x00 = at(i0[0], i0[1], i0[2]).lerp(at(i1[0], i0[1], i0[2]), t[0]);
    let x10 = at(i0[0], i1[1], i0[2]).lerp(at(i1[0], i1[1], i0[2]), t[0]);
    let x01 = at(i0[0], i0[1], i1[2]).lerp(at(i1[0], i0[1], i1[2]), t[0]);
    let x11 = at(i0[0], i1[1], i1[2]).lerp(at(i1[0], i1[1], i1[2]), t[0]);
    x00.lerp(x10, t[1]).lerp(x01.lerp(x11, t[1]), t[2])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bone_points_follow_their_group_rigidly() {
        let flex = Flexion::knee(60.0);
        let inverse = flex.inverse_rotations(LATTICE_STEPS);
        // A point inside the tibial shaft and one inside the femoral shaft.
        for (straight, label) in [
            (Vec3::new(0.0, -1.0, -120.0), 3u16),
            (Vec3::new(0.0, -2.0, 120.0), 2),
        ] {
            let m = flex.bone_matrix(label);
            let bent = m * nalgebra::Vector4::new(
                straight.x as f64,
                straight.y as f64,
                straight.z as f64,
                1.0,
            );
            let bent = Vec3::new(bent.x as f32, bent.y as f32, bent.z as f32);
            let back = flex.straight_point(bent, &inverse);
            assert!(
                (back - straight).length() < 1e-3,
                "{label}: {back} vs {straight}"
            );
        }
    }
}
