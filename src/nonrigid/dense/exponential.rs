//! exp(v) of a stationary velocity by scaling and squaring, and the exponential a level's
//! velocity joins the field with: one whose Jacobian determinant is positive on the grid.
//!
//! The flow of a smooth velocity is invertible, but its exponential on a grid need not be:
//! where a coarse level's velocity pushes tissue against a bone, on which the velocity is held
//! at zero, the tissue is squeezed into a voxel or two and the squarings' trilinear samples
//! cross (2 mm 90° volume-keeping knee: 29 voxels with det ≤ 0, 1 mm: 147, at one and two
//! voxels from a bone, the velocity 14 and 19 mm long there). More squarings do not help
//! (5 → 11: 29 → 26 voxels); scaling the whole velocity down until none folds costs the soft
//! tissue 0.8 mm there (4.25 → 5.03), a wider bone margin at the coarse levels as much. So the
//! velocity is faded to zero around the voxels that fold alone, over half its length, which
//! bounds how fast it falls toward them (BENCHMARKS.md, thirty-eighth session).

use crate::abi::dense::CombineParams;
use crate::abi::{ComposeParams, ThresholdParams};
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use crate::images::fold_repair::{determinant, Folds};
use crate::images::regions;
use crate::volume::Grid;

/// Largest vector of v / 2ⁿ (voxels) before it is squared: small against a voxel, so that
/// the first map is invertible (half a voxel, as log-domain demons choose it).
const SQUARING_START_VOXELS: f64 = 0.5;
/// Most times a velocity is faded around the voxels where its exponential folds.
const MOST_FADES: usize = 4;
/// The fade around folded voxels rises over this share of the velocity's longest vector: the
/// velocity then falls toward a fold at most twice as fast as its length (per unit time of
/// the flow, squeezing by at most e⁻² there). A share of 0.25 left folds on the 1 mm knee
/// after four fades; 1 cost it 0.14 mm (BENCHMARKS.md, thirty-eighth session).
const FADE_SHARE: f64 = 0.5;

/// exp(v) with the velocity faded where it folds, and what that took.
pub struct Exponential<B: Backend> {
    /// The map (3 floats per voxel, mm).
    pub map: DeviceImage<B>,
    /// Squarings taken.
    pub squarings: u32,
    /// The map's fold statistics (its smallest determinant above 0 unless folds outlasted
    /// every fade).
    pub folds: Folds,
    /// Voxels with det ≤ 0 before each fade, summed over the fades (0: exp(v) did not fold).
    pub faded: usize,
}

/// exp(v) on `grid` for a velocity whose vectors are at most `bound` mm long; where it folds
/// (det J ≤ 0), v is faded to zero at the folded voxels, rising to its whole over
/// [`FADE_SHARE`] of `bound` around them, and taken again, at most [`MOST_FADES`] times. Fading
/// never lengthens v, and where v was zero (the bones) it stays zero.
pub fn unfolded<B: Backend>(
    backend: &B,
    grid: &Grid,
    mut v: B::Buffer<f32>,
    bound: f64,
) -> Result<Exponential<B>> {
    let squarings = squarings(bound, grid);
    let nothing_held = backend.zeros("nothing held", grid.len())?;
    let folded = ThresholdParams::new(grid, 0.0);
    let fade = CombineParams::sum(grid, 1.0, 0.0).faded(FADE_SHARE * bound);
    let mut faded = 0;
    for fades in 0.. {
        let map = DeviceImage {
            data: exponential(backend, grid, &v, squarings)?,
            grid: grid.clone(),
        };
        let (det, folds) = determinant(backend, &map, &nothing_held)?;
        if folds.folded == 0 || fades == MOST_FADES {
            return Ok(Exponential {
                map,
                squarings,
                folds,
                faded,
            });
        }
        faded += folds.folded;
        let marked = DeviceImage {
            data: backend.mark_at_most(&folded, &det, &nothing_held)?,
            grid: grid.clone(),
        };
        let distance = regions::distance_to_nearest(backend, &marked)?;
        v = backend.field_combine(&fade, &v, &v, &distance)?;
    }
    unreachable!("the fades end at MOST_FADES")
}

/// Squarings that bring a velocity whose vectors are at most `bound` mm long below
/// [`SQUARING_START_VOXELS`] of `grid`'s finest voxel.
pub fn squarings(bound: f64, grid: &Grid) -> u32 {
    let ratio = bound / (SQUARING_START_VOXELS * grid.finest_spacing());
    if ratio <= 1.0 {
        0
    } else {
        ratio.log2().ceil().min(20.0) as u32
    }
}

/// exp(v) by scaling and squaring: v / 2ⁿ composed with itself n times (3 floats per voxel of
/// `grid`, mm).
pub fn exponential<B: Backend>(
    backend: &B,
    grid: &Grid,
    v: &B::Buffer<f32>,
    squarings: u32,
) -> Result<B::Buffer<f32>> {
    let scale = 0.5f64.powi(squarings as i32);
    let mut phi = backend.field_combine(&CombineParams::sum(grid, scale, 0.0), v, v, v)?;
    let params = ComposeParams::new(grid, grid);
    for _ in 0..squarings {
        phi = backend.compose(&params, &phi, &phi)?;
    }
    Ok(phi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::backend::Core;
    use crate::cpu::CpuBackend;
    use crate::images::fold_repair::determinant;

    /// A 1 mm grid of `n`³ voxels.
    fn grid(n: usize) -> Grid {
        Grid::new([n; 3], crate::volume::Affine::identity()).unwrap()
    }

    /// Tissue pushed against a held ball of radius `r` at the grid's centre: v = 0 on the
    /// ball, `length` mm long and pointing at the centre from `ramp` mm beyond its surface, as
    /// a coarse level's velocity sampled beside a bone can be.
    fn pushed_against_a_ball(n: usize, r: f32, (length, ramp): (f32, f32)) -> Vec<f32> {
        let c = (n as f32 - 1.0) / 2.0;
        let mut v = vec![0.0f32; 3 * n * n * n];
        for (voxel, vector) in v.chunks_exact_mut(3).enumerate() {
            let p = [voxel % n, voxel / n % n, voxel / (n * n)].map(|i| i as f32 - c);
            let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            let speed = length * ((d - r) / ramp).clamp(0.0, 1.0);
            for a in 0..3 {
                vector[a] = -speed * p[a] / d.max(1e-6);
            }
        }
        v
    }

    #[test]
    fn an_exponential_that_folds_is_faded_until_it_does_not_and_the_held_voxels_stay_put() {
        let (n, r) = (24, 3.0);
        let grid = grid(n);
        let (length, ramp) = (12.0, 2.0);
        let data = pushed_against_a_ball(n, r, (length, ramp));
        let v = CpuBackend.upload("velocity", data.clone()).unwrap();
        let bound = length as f64;
        // The scenario folds as it stands (else the fade below would test nothing).
        let raw = DeviceImage {
            data: exponential(&CpuBackend, &grid, &v, squarings(bound, &grid)).unwrap(),
            grid: grid.clone(),
        };
        let nothing = CpuBackend.zeros("nothing held", grid.len()).unwrap();
        let (_, raw_folds) = determinant(&CpuBackend, &raw, &nothing).unwrap();
        assert!(raw_folds.folded > 0, "exp(v) does not fold: {raw_folds:?}");

        let exp = unfolded(&CpuBackend, &grid, v, bound).unwrap();
        assert!(exp.folds.min > 0.0, "still folds: {:?}", exp.folds);
        assert!(exp.faded >= raw_folds.folded, "{} faded", exp.faded);
        let map = CpuBackend.download_one(&exp.map.data).unwrap();
        for (voxel, (u, v)) in map.chunks_exact(3).zip(data.chunks_exact(3)).enumerate() {
            if v == [0.0; 3] {
                assert_eq!(u, [0.0; 3], "voxel {voxel}, where v is zero, moved");
            }
        }
    }

    #[test]
    fn squarings_bring_the_velocity_below_half_a_voxel() {
        let mut affine = crate::volume::Affine::identity();
        for a in 0..3 {
            affine[(a, a)] = 2.0;
        }
        let grid = Grid::new([8, 8, 8], affine).unwrap();
        assert_eq!(squarings(0.0, &grid), 0);
        assert_eq!(squarings(1.0, &grid), 0);
        assert_eq!(squarings(1.1, &grid), 1);
        assert_eq!(squarings(8.0, &grid), 3);
    }
}
