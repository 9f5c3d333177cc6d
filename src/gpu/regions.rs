//! Host side of shaders/edt.wgsl and shaders/moments.wgsl: distance maps and region moments.

use super::kernel::{groups, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::{EdtParams, MomentsParams};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// edt bindings in the order the shader declares them.
pub const EDT_BINDINGS: &[Binding] = &[Uniform, Read, ReadWrite];
/// moments bindings.
pub const MOMENTS_BINDINGS: &[Binding] = &[Uniform, Read, ReadWrite];

impl GpuBackend {
    /// One axis's pass of the distance maps, one invocation per line.
    pub fn record_edt(&self, params: &EdtParams, input: &GpuBuffer<f32>) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("distance maps", params.values())?;
        let [a, b] = params.lines();
        self.record(
            &self.kernels.edt,
            params,
            &[input.raw(), out.raw()],
            [groups(a, 8), groups(b, 8), params.stack[0]],
        )?;
        Ok(out)
    }

    /// Count and position sums per chunk.
    pub fn record_moments(
        &self,
        params: &MomentsParams,
        values: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f64>> {
        let out = self.output_buffer("region moments", 4 * params.chunks())?;
        self.record(
            &self.kernels.moments,
            params,
            &[values.raw(), out.raw()],
            [groups(params.chunks(), 64), 1, 1],
        )?;
        Ok(out)
    }
}
