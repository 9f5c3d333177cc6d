//! Host side of shaders/skin_weights.wgsl and shaders/skin_blend.wgsl.

use super::kernel::{cover, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::{SkinBlendParams, SkinWeightsParams};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// skin_weights bindings in the order the shader declares them.
pub const WEIGHTS_BINDINGS: &[Binding] = &[Uniform, Read, ReadWrite];
/// skin_blend bindings in the order the shader declares them.
pub const BLEND_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite, ReadWrite];

impl GpuBackend {
    /// Weights from distances (bones per voxel each).
    pub fn record_skin_weights(
        &self,
        params: &SkinWeightsParams,
        distances: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let weights = self.output_buffer("skinning weights", params.values())?;
        self.record(
            &self.kernels.skin_weights,
            params,
            &[distances.raw(), weights.raw()],
            cover(params.dims, 4),
        )?;
        Ok(weights)
    }

    /// The inverted blend: u (3 floats per target voxel) and its residual (1 float).
    pub fn record_skin_blend(
        &self,
        params: &SkinBlendParams,
        weights: &GpuBuffer<f32>,
        bone_of_voxel: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let field = self.output_buffer("inverted blend", 3 * params.voxels())?;
        let residual = self.output_buffer("inversion residual", params.voxels())?;
        self.record(
            &self.kernels.skin_blend,
            params,
            &[
                weights.raw(),
                bone_of_voxel.raw(),
                field.raw(),
                residual.raw(),
            ],
            cover(params.dims, 4),
        )?;
        Ok((field, residual))
    }
}
