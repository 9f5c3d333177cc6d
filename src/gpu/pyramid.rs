//! Host side of shaders/pyramid.wgsl.

use super::kernel::{groups, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::PyramidParams;
use crate::error::Result;

/// Bindings in the order the shader declares them.
pub const BINDINGS: &[Binding] = &[Binding::Uniform, Binding::Read, Binding::ReadWrite];

impl GpuBackend {
    /// One coarser level, the whole grid in one dispatch.
    pub fn record_pyramid(
        &self,
        params: &PyramidParams,
        input: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("pyramid level", params.output_len())?;
        let [nx, ny, nz, _] = params.dims;
        self.record(
            &self.kernels.pyramid,
            params,
            &[input.raw(), out.raw()],
            [nx, ny, nz].map(|n| groups(n as usize, 4)),
        )?;
        Ok(out)
    }
}
