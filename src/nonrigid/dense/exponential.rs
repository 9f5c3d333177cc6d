//! exp(v) of a stationary velocity by scaling and squaring, and the exponential a level's
//! velocity joins the field with: one whose Jacobian determinant is positive on the grid.
//!
//! The flow of a smooth velocity is invertible, but its exponential on a grid need not be:
//! where a coarse level's velocity pushes tissue against a bone, on which the velocity is held
//! at zero, the tissue is squeezed into a voxel or two and the squarings' trilinear samples
//! cross (2 mm 90° volume-keeping knee: 29 voxels with det ≤ 0, 1 mm: 147, at one and two
//! voxels from a bone, the velocity up to 14 and 19 mm long there). More squarings do not help
//! (5 → 11: 29 → 26 voxels); scaling the whole velocity down until none folds costs the soft
//! tissue 0.8 mm there (4.25 → 5.03), a wider bone margin at the coarse levels as much. So the
//! velocity is faded to zero around the folded voxels alone, over half its longest vector,
//! which bounds how fast one fade makes it fall toward them (BENCHMARKS.md, thirty-eighth
//! session). Where folds outlast [`MOST_FADES`] fades the last map is kept and its determinant
//! reported (report.json's dense `min_det`, the log).

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
/// The fade around folded voxels rises over this share of the velocity's longest vector: one
/// fade makes the velocity fall toward a fold at most about twice as fast as its length (per
/// unit time of the flow, squeezing by about e⁻² there). Measured on the three pairs that fold
/// (2 mm 45° / 90°, 1 mm 90°, volume kept): a fixed 4 mm left folds after four fades, 8 mm left
/// 2 voxels on the 1 mm pair; half the longest vector ended them in one fade (soft tissue 2.10 /
/// 4.26 / 4.30 mm against 2.09 / 4.25 / 4.21 unfaded), the whole of it cost more (2.11 / 4.44 /
/// 4.35; BENCHMARKS.md, thirty-eighth session).
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
    /// Fades taken (0: exp(v) did not fold).
    pub fades: usize,
    /// Voxels with det ≤ 0 before each fade, summed over the fades.
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
                fades,
                faded,
            });
        }
        faded += folds.folded;
        let marked = DeviceImage {
            data: backend.mark_at_most(&folded, &det, &nothing_held)?,
            grid: grid.clone(),
        };
        let distance = regions::distance_to_nearest(backend, &marked)?;
        let around_folds = Some((distance, FADE_SHARE * bound));
        v = super::combine(backend, grid, &around_folds, (1.0, &v), (0.0, &v))?;
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
