//! Host side of shaders/jacobian.wgsl.

use super::buffer::{storage_from, storage_output, submit_and_read, uniform_from};
use super::context::GpuContext;
use super::kernel::{groups, Binding, Kernel};
use super::Slab;
use crate::abi::JacobianParams;
use crate::error::Result;

/// Bindings in the order the shader declares them.
pub const BINDINGS: &[Binding] = &[Binding::Uniform, Binding::Read, Binding::ReadWrite];

/// Bytes per voxel of the largest per-slab binding (the packed field).
pub const FIELD_BYTES_PER_VOXEL: usize = 12;

/// Slabs need one halo slice each side: plan with room for it.
pub const HALO_SLICES: usize = 2;

/// det(I + du/dx) for every voxel, slab by slab.
pub fn jacobian(
    ctx: &GpuContext,
    kernel: &Kernel,
    params: &JacobianParams,
    field: &[f32],
    slabs: &[Slab],
) -> Result<Vec<f32>> {
    let [nx, ny, nz, _] = params.dims.map(|v| v as usize);
    let slice = nx * ny;
    let mut det = Vec::with_capacity(slice * nz);
    for slab in slabs {
        let first = slab.z0.saturating_sub(1);
        let last = (slab.z0 + slab.depth + 1).min(nz);
        let uniform = uniform_from(
            ctx,
            "jacobian parameters",
            &params.slab(slab.z0 as u32, slab.depth as u32, first as u32),
        )?;
        let field_buffer = storage_from(
            ctx,
            "displacement field slab",
            &field[3 * first * slice..3 * last * slice],
        )?;
        let voxels = slab.depth * slice;
        let output = storage_output::<f32>(ctx, "jacobian slab", voxels)?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        kernel.dispatch(
            ctx,
            &mut encoder,
            &[&uniform, &field_buffer, &output],
            [groups(nx, 4), groups(ny, 4), groups(slab.depth, 4)],
        )?;
        det.extend(submit_and_read::<f32>(ctx, encoder, &output, voxels)?);
    }
    Ok(det)
}
