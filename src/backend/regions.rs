//! Regions of a label map: distance maps and moments (shaders/regions/, abi::regions,
//! cpu::regions, gpu::regions).

use super::Core;
use crate::abi::{EdtParams, MomentsParams};
use crate::error::Result;

/// Kernels measuring regions.
pub trait Regions: Core {
    /// One axis's pass of exact Euclidean distance maps (mm) for a stack of volumes
    /// (`params`): the first pass reads a label index map, the others the stack.
    fn edt(&self, params: &EdtParams, input: &Self::Buffer<f32>) -> Result<Self::Buffer<f32>>;

    /// Per chunk of abi::STATS_CHUNK voxels of `values`: how many are at or above `params`'
    /// threshold and the sum of their world positions (4 f64 each).
    fn moments(
        &self,
        params: &MomentsParams,
        values: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f64>>;
}
