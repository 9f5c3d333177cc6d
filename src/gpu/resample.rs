//! Host side of shaders/resample.wgsl.

use super::buffer::{storage_from, storage_output, submit_and_read, uniform_from};
use super::context::GpuContext;
use super::kernel::{groups, Binding, Kernel};
use super::Slab;
use crate::abi::ResampleParams;
use crate::error::Result;

/// Bindings in the order the shader declares them.
pub const BINDINGS: &[Binding] = &[
    Binding::Uniform,
    Binding::Read,
    Binding::Read,
    Binding::ReadWrite,
];

/// Bytes per target voxel held in per-slab buffers (the packed field, 12, and the output, 4);
/// the field is the largest single binding.
pub const FIELD_BYTES_PER_VOXEL: usize = 12;

/// Resamples slab by slab; returns the warped values of every target voxel, x fastest.
pub fn resample(
    ctx: &GpuContext,
    kernel: &Kernel,
    params: &ResampleParams,
    source: &[f32],
    field: &[f32],
    slabs: &[Slab],
) -> Result<Vec<f32>> {
    let [nx, ny, nz, _] = params.target_dims.map(|v| v as usize);
    let slice = nx * ny;
    let source_buffer = storage_from(ctx, "source volume", source)?;
    let mut warped = Vec::with_capacity(slice * nz);
    for slab in slabs {
        let voxels = slab.depth * slice;
        let uniform = uniform_from(
            ctx,
            "resample parameters",
            &params.slab(slab.z0 as u32, slab.depth as u32),
        )?;
        let start = slab.z0 * slice;
        let field_buffer = storage_from(
            ctx,
            "displacement field slab",
            &field[3 * start..3 * (start + voxels)],
        )?;
        let output = storage_output::<f32>(ctx, "warped slab", voxels)?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        kernel.dispatch(
            ctx,
            &mut encoder,
            &[&uniform, &source_buffer, &field_buffer, &output],
            [groups(nx, 4), groups(ny, 4), groups(slab.depth, 4)],
        )?;
        warped.extend(submit_and_read::<f32>(ctx, encoder, &output, voxels)?);
    }
    Ok(warped)
}
