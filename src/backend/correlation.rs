//! The local correlation of two images: box sums, the correlation and the cost's terms and
//! gradient through a warp (shaders/correlation/, abi::correlation, cpu::correlation,
//! gpu::correlation).

use super::Core;
use crate::abi::{LnccParams, LnccTermsParams, LocalMomentsParams, RbfGradParams};
use crate::error::Result;

/// Kernels of the local normalised cross-correlation.
pub trait Correlation: Core {
    /// One axis's pass of box sums (`params`) for the local correlation of two images: the
    /// first pass sums abi::LOCAL_MOMENTS of the images `input` (a) and `other` (b) along x,
    /// the others sum the stack in `input` along y, then z (`other` unused).
    fn local_moments(
        &self,
        params: &LocalMomentsParams,
        input: &Self::Buffer<f32>,
        other: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// Per chunk of abi::STATS_CHUNK voxels of box sums (`local_moments`' last pass): the sum
    /// of the squared local correlation and the voxels where it is defined (neither window
    /// flat).
    fn lncc(&self, params: &LnccParams, sums: &Self::Buffer<f32>) -> Result<Self::Buffer<f32>>;

    /// The local-correlation cost's terms from the box sums of W and T (`local_moments`' last
    /// pass) and the coverage: 5 floats per voxel to box-sum again (`local_moments` over
    /// `LocalMomentsParams::stack_passes`) and K Σ c (1 − ρ²) per row of x (ny · nz floats).
    fn lncc_terms(
        &self,
        params: &LnccTermsParams,
        sums: &Self::Buffer<f32>,
        covered: &Self::Buffer<f32>,
    ) -> Result<(Self::Buffer<f32>, Self::Buffer<f32>)>;

    /// The image part of the local-correlation cost's gradient through the warp `lattice`
    /// (3 floats per voxel, as `warp_cost`'s) from the box-summed terms `summed`: `moving`
    /// (I0) seen through it against `fixed`.
    fn lncc_gradient(
        &self,
        params: &RbfGradParams,
        lattice: &Self::Buffer<f32>,
        moving: &Self::Buffer<f32>,
        fixed: &Self::Buffer<f32>,
        summed: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;
}

/// The box sums of the local correlation (abi::LOCAL_MOMENTS per voxel) of the images `a` and
/// `b` on one grid: `passes` (`LocalMomentsParams::passes`) x, y, then z; or, with
/// `LocalMomentsParams::stack_passes`, of the stack in `a` (`b` unused).
pub fn box_sums<B: Correlation>(
    backend: &B,
    passes: &[LocalMomentsParams; 3],
    a: &B::Buffer<f32>,
    b: &B::Buffer<f32>,
) -> Result<B::Buffer<f32>> {
    let along_x = backend.local_moments(&passes[0], a, b)?;
    let along_y = backend.local_moments(&passes[1], &along_x, &along_x)?;
    backend.local_moments(&passes[2], &along_y, &along_y)
}
