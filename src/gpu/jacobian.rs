//! Host side of shaders/jacobian.wgsl.

use super::kernel::{cover, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::JacobianParams;
use crate::error::Result;

/// Bindings in the order the shader declares them.
pub const BINDINGS: &[Binding] = &[Binding::Uniform, Binding::Read, Binding::ReadWrite];

impl GpuBackend {
    /// det(I + du/dx) for every voxel.
    pub fn record_jacobian(
        &self,
        params: &JacobianParams,
        field: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let det = self.output_buffer("Jacobian determinant", params.voxels())?;
        self.record(
            &self.kernels.jacobian,
            params,
            &[field.raw(), det.raw()],
            cover(params.dims, 4),
        )?;
        Ok(det)
    }
}
