//! Host side of shaders/label_index.wgsl and shaders/bone_at_source.wgsl.

use super::kernel::{cover, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::{BoneLookupParams, LabelParams};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// label_index bindings in the order the shader declares them.
pub const INDEX_BINDINGS: &[Binding] = &[Uniform, Read, ReadWrite];
/// bone_at_source bindings.
pub const BONE_BINDINGS: &[Binding] = &[Uniform, Read, Read, Read, ReadWrite];

impl GpuBackend {
    /// Each label's position among the codes.
    pub fn record_label_index(
        &self,
        params: &LabelParams,
        labels: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let index = self.output_buffer("label index", params.voxels())?;
        self.record(
            &self.kernels.label_index,
            params,
            &[labels.raw(), index.raw()],
            cover(params.dims, 4),
        )?;
        Ok(index)
    }

    /// The bone at each target voxel's source point.
    pub fn record_bone_at_source(
        &self,
        params: &BoneLookupParams,
        field: &GpuBuffer<f32>,
        residual: &GpuBuffer<f32>,
        labels: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let bone = self.output_buffer("bone at the source point", params.voxels())?;
        self.record(
            &self.kernels.bone_at_source,
            params,
            &[field.raw(), residual.raw(), labels.raw(), bone.raw()],
            cover(params.geometry.target_dims, 4),
        )?;
        Ok(bone)
    }
}
