//! Volume skinning: weights from distance maps and the inverted blend (shaders/skinning/,
//! abi::skinning, cpu::skinning, gpu::skinning).

use super::Core;
use crate::abi::{SkinBlendParams, SkinWeightsParams};
use crate::error::Result;

/// Kernels of the skeletal deformation.
pub trait Skinning: Core {
    /// Skinning weights (bones per voxel) from distance maps (bones per voxel, mm).
    fn skin_weights(
        &self,
        params: &SkinWeightsParams,
        distances: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// The inverted blend on the target grid: u (3 floats per voxel, mm) and the inversion
    /// residual (1 float per voxel, mm) for bones moving and blended as `params` says,
    /// `weights` (bones per voxel) on the weight grid, and `bone_of_voxel` (1 + bone index, 0
    /// for soft tissue) on the source label grid.
    fn skin_blend(
        &self,
        params: &SkinBlendParams,
        weights: &Self::Buffer<f32>,
        bone_of_voxel: &Self::Buffer<f32>,
    ) -> Result<(Self::Buffer<f32>, Self::Buffer<f32>)>;
}
