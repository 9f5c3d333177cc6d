//! Host side of shaders/ssd_cells.wgsl.

use super::buffer::{storage_from, storage_output, submit_and_read, uniform_from};
use super::context::GpuContext;
use super::kernel::{groups, Binding, Kernel};
use super::Slab;
use crate::abi::SsdParams;
use crate::error::Result;

/// Bindings in the order the shader declares them.
pub const BINDINGS: &[Binding] = &[
    Binding::Uniform,
    Binding::Read,
    Binding::Read,
    Binding::ReadWrite,
];

/// Bytes per voxel of the largest per-slab binding (one f32 volume).
pub const BYTES_PER_VOXEL: usize = 4;

/// Column partial sums for the whole volume (layout of metric::fold_ssd_partials).
pub fn ssd_partials(
    ctx: &GpuContext,
    kernel: &Kernel,
    dims: [usize; 3],
    cells: [usize; 3],
    a: &[f32],
    b: &[f32],
    slabs: &[Slab],
) -> Result<Vec<f32>> {
    let [nx, ny, nz] = dims;
    let slice = nx * ny;
    let mut partial = Vec::with_capacity(nz * nx * cells[1]);
    for slab in slabs {
        let range = slab.z0 * slice..(slab.z0 + slab.depth) * slice;
        let uniform = uniform_from(
            ctx,
            "ssd parameters",
            &SsdParams::new(dims, cells, slab.depth),
        )?;
        let a_buffer = storage_from(ctx, "ssd first volume slab", &a[range.clone()])?;
        let b_buffer = storage_from(ctx, "ssd second volume slab", &b[range])?;
        let len = slab.depth * nx * cells[1];
        let output = storage_output::<f32>(ctx, "ssd partial sums", len)?;
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        kernel.dispatch(
            ctx,
            &mut encoder,
            &[&uniform, &a_buffer, &b_buffer, &output],
            [groups(nx, 64), slab.depth as u32, 1],
        )?;
        partial.extend(submit_and_read::<f32>(ctx, encoder, &output, len)?);
    }
    Ok(partial)
}
