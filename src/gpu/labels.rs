//! Host side of the label family (shaders/labels/): its bindings, its compiled pipelines and
//! the family's trait.

use super::context::GpuContext;
use super::kernel::{cover, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::{BoneLookupParams, LabelParams, SurfaceParams};
use crate::backend::labels::LabelMaps;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("label_index", &[Uniform, Read, ReadWrite]),
    ("bone_at_source", &[Uniform, Read, Read, Read, ReadWrite]),
    ("region_surface", &[Uniform, Read, ReadWrite]),
];

/// The family's compiled kernels.
pub struct LabelKernels {
    label_index: Kernel,
    bone_at_source: Kernel,
    region_surface: Kernel,
}

impl LabelKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(LabelKernels {
            label_index: compile(ctx, "label_index")?,
            bone_at_source: compile(ctx, "bone_at_source")?,
            region_surface: compile(ctx, "region_surface")?,
        })
    }
}

impl LabelMaps for GpuBackend {
    /// Each label's position among the codes.
    fn label_index(&self, params: &LabelParams, labels: &GpuBuffer<f32>) -> Result<GpuBuffer<f32>> {
        let index = self.output_buffer("label index", params.voxels())?;
        self.record(
            &self.kernels.labels.label_index,
            params,
            &[labels.raw(), index.raw()],
            cover(params.dims, 4),
        )?;
        Ok(index)
    }

    /// The bone at each target voxel's source point.
    fn bone_at_source(
        &self,
        params: &BoneLookupParams,
        field: &GpuBuffer<f32>,
        residual: &GpuBuffer<f32>,
        labels: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let bone = self.output_buffer("bone at the source point", params.voxels())?;
        self.record(
            &self.kernels.labels.bone_at_source,
            params,
            &[field.raw(), residual.raw(), labels.raw(), bone.raw()],
            cover(params.geometry.target_dims, 4),
        )?;
        Ok(bone)
    }

    /// Each region's boundary voxels.
    fn region_surface(
        &self,
        params: &SurfaceParams,
        regions: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let surface = self.output_buffer("region surfaces", params.voxels())?;
        self.record(
            &self.kernels.labels.region_surface,
            params,
            &[regions.raw(), surface.raw()],
            cover(params.dims, 4),
        )?;
        Ok(surface)
    }
}
