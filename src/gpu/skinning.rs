//! Host side of the skinning family (shaders/skinning/): its bindings, its compiled pipelines
//! and the family's trait.

use super::context::GpuContext;
use super::kernel::{cover, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::{SkinBlendParams, SkinWeightsParams};
use crate::backend::skinning::Skinning;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("skin_weights", &[Uniform, Read, ReadWrite]),
    ("skin_blend", &[Uniform, Read, Read, ReadWrite, ReadWrite]),
];

/// The family's compiled kernels.
pub struct SkinningKernels {
    skin_weights: Kernel,
    skin_blend: Kernel,
}

impl SkinningKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(SkinningKernels {
            skin_weights: compile(ctx, "skin_weights")?,
            skin_blend: compile(ctx, "skin_blend")?,
        })
    }
}

impl Skinning for GpuBackend {
    /// Weights from distances (bones per voxel each).
    fn skin_weights(
        &self,
        params: &SkinWeightsParams,
        distances: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let weights = self.output_buffer("skinning weights", params.values())?;
        self.record(
            &self.kernels.skinning.skin_weights,
            params,
            &[distances.raw(), weights.raw()],
            cover(params.dims, 4),
        )?;
        Ok(weights)
    }

    /// The inverted blend: u (3 floats per target voxel) and its residual (1 float).
    fn skin_blend(
        &self,
        params: &SkinBlendParams,
        weights: &GpuBuffer<f32>,
        bone_of_voxel: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let field = self.output_buffer("inverted blend", 3 * params.voxels())?;
        let residual = self.output_buffer("inversion residual", params.voxels())?;
        self.record(
            &self.kernels.skinning.skin_blend,
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
