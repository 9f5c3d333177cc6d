//! Host side of the sampling family (shaders/sampling/): resample, coverage and pyramid
//! levels: their bindings, their compiled pipelines and the family's trait.

use super::context::GpuContext;
use super::kernel::{cover, groups, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::{PyramidParams, ResampleParams};
use crate::backend::sampling::Sampling;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("resample", &[Uniform, Read, Read, ReadWrite]),
    ("coverage", &[Uniform, Read, Read, ReadWrite]),
    ("pyramid", &[Uniform, Read, ReadWrite]),
];

/// The family's compiled kernels.
pub struct SamplingKernels {
    resample: Kernel,
    coverage: Kernel,
    pyramid: Kernel,
}

impl SamplingKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(SamplingKernels {
            resample: compile(ctx, "resample")?,
            coverage: compile(ctx, "coverage")?,
            pyramid: compile(ctx, "pyramid")?,
        })
    }
}

impl Sampling for GpuBackend {
    fn resample(
        &self,
        params: &ResampleParams,
        source: &GpuBuffer<f32>,
        field: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let warped = self.output_buffer("resampled image", params.voxels())?;
        self.record(
            &self.kernels.sampling.resample,
            params,
            &[source.raw(), field.raw(), warped.raw()],
            cover(params.target_dims, 4),
        )?;
        Ok(warped)
    }

    fn coverage(
        &self,
        params: &ResampleParams,
        field: &GpuBuffer<f32>,
        mask: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let covered = self.output_buffer("coverage", params.voxels())?;
        self.record(
            &self.kernels.sampling.coverage,
            params,
            &[field.raw(), mask.raw(), covered.raw()],
            cover(params.target_dims, 4),
        )?;
        Ok(covered)
    }

    /// One coarser level, the whole grid in one dispatch.
    fn pyramid_level(
        &self,
        params: &PyramidParams,
        input: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("pyramid level", params.output_len())?;
        let [nx, ny, nz, _] = params.dims;
        self.record(
            &self.kernels.sampling.pyramid,
            params,
            &[input.raw(), out.raw()],
            [nx, ny, nz].map(|n| groups(n as usize, 4)),
        )?;
        Ok(out)
    }
}
