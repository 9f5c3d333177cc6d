//! Host side of shaders/local_moments.wgsl and shaders/lncc.wgsl: the local correlation of two
//! images.

use super::kernel::{cover, groups, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::{LnccParams, LocalMomentsParams};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// local_moments bindings in the order the shader declares them.
pub const MOMENTS_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];
/// lncc bindings.
pub const LNCC_BINDINGS: &[Binding] = &[Uniform, Read, ReadWrite];

impl GpuBackend {
    /// One axis's pass of the box sums.
    pub fn record_local_moments(
        &self,
        params: &LocalMomentsParams,
        input: &GpuBuffer<f32>,
        other: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("local moments", params.values())?;
        self.record(
            &self.kernels.local_moments,
            params,
            &[input.raw(), other.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// 2 floats per chunk: Σ ρ² and the voxels counted.
    pub fn record_lncc(
        &self,
        params: &LnccParams,
        sums: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("local correlation sums", 2 * params.chunks())?;
        self.record(
            &self.kernels.lncc,
            params,
            &[sums.raw(), out.raw()],
            [groups(params.chunks(), 64), 1, 1],
        )?;
        Ok(out)
    }
}
