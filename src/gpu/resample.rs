//! Host side of shaders/resample.wgsl and shaders/coverage.wgsl.

use super::kernel::{cover, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::ResampleParams;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// resample bindings in the order the shader declares them.
pub const BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];
/// coverage bindings.
pub const COVERAGE_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];

impl GpuBackend {
    /// The source sampled through the field at every target voxel.
    pub fn record_resample(
        &self,
        params: &ResampleParams,
        source: &GpuBuffer<f32>,
        field: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let warped = self.output_buffer("resampled image", params.voxels())?;
        self.record(
            &self.kernels.resample,
            params,
            &[source.raw(), field.raw(), warped.raw()],
            cover(params.target_dims, 4),
        )?;
        Ok(warped)
    }

    /// 1 where a target voxel's source point is inside the source, else 0.
    pub fn record_coverage(
        &self,
        params: &ResampleParams,
        field: &GpuBuffer<f32>,
        mask: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let covered = self.output_buffer("coverage", params.voxels())?;
        self.record(
            &self.kernels.coverage,
            params,
            &[field.raw(), mask.raw(), covered.raw()],
            cover(params.target_dims, 4),
        )?;
        Ok(covered)
    }
}
