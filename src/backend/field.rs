//! The final field's kernels: the warp on the grid, its fade off the bones, composition with
//! the initial field and inversion (shaders/field/, abi::field, cpu::field, gpu::field).

use super::Core;
use crate::abi::{ComposeParams, FadeParams, InvertParams, RbfGradParams, RoundTripParams};
use crate::error::Result;

/// Kernels of displacement fields (named `Fields`: crate::volume::Field is the field itself).
pub trait Fields: Core {
    /// The warp R at every voxel of the grid in `params` (3 floats per voxel), interpolated
    /// from `lattice` (3 floats per node) as the non-rigid cost does.
    fn warp_field(
        &self,
        params: &RbfGradParams,
        lattice: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// The total field u = R + u0 ∘ (id + R) of a warp R and an initial field u0 on one grid.
    fn compose(
        &self,
        params: &ComposeParams,
        warp: &Self::Buffer<f32>,
        initial: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// `warp` (3 floats per voxel of the grid in `params`) scaled by each voxel's distance to
    /// the nearest bone (`distance`, mm: images::regions::distance_to_nearest) over the margin,
    /// clamped to 1: zero on the bones.
    fn fade_warp(
        &self,
        params: &FadeParams,
        warp: &Self::Buffer<f32>,
        distance: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// The inverse of `field` (3 floats per voxel of the field grid in `params`) on the output
    /// grid: w with y + w(y) = z where z + u(z) = y (3 floats per voxel), and per voxel the
    /// residual |z + u(z) − y| in mm, −1 where y has no preimage in the field's grid.
    fn invert_field(
        &self,
        params: &InvertParams,
        field: &Self::Buffer<f32>,
    ) -> Result<(Self::Buffer<f32>, Self::Buffer<f32>)>;

    /// Per chunk of `params`' source voxels inside the body (`source` > 0): the sum and largest
    /// of the round-trip `residual`s (mm) of those with a preimage (≥ 0), their count, those
    /// beyond `params`' far distance, and the count without a preimage (abi::ROUND_TRIP_WIDTH
    /// values, in f64).
    fn round_trip_stats(
        &self,
        params: &RoundTripParams,
        residual: &Self::Buffer<f32>,
        source: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f64>>;
}
