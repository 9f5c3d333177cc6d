//! CPU twins of the skinning family's kernels (shaders/skinning/).

mod skin_blend;
mod skin_weights;

use super::{filled, filled_pair, CpuBackend};
use crate::abi::{SkinBlendParams, SkinWeightsParams};
use crate::backend::skinning::Skinning;
use crate::error::Result;
use std::sync::Arc;

impl Skinning for CpuBackend {
    fn skin_weights(
        &self,
        params: &SkinWeightsParams,
        distances: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.values(), |out| {
            skin_weights::skin_weights(params, distances, out)
        })
    }

    fn skin_blend(
        &self,
        params: &SkinBlendParams,
        weights: &Arc<Vec<f32>>,
        bone_of_voxel: &Arc<Vec<f32>>,
    ) -> Result<(Arc<Vec<f32>>, Arc<Vec<f32>>)> {
        filled_pair([3 * params.voxels(), params.voxels()], |field, residual| {
            skin_blend::skin_blend(params, weights, bone_of_voxel, field, residual);
        })
    }
}
