//! The one way kernels are run on the GPU: upload inputs, split the output into slabs of whole
//! z-slices that fit the device's binding limits, dispatch, read back. Each kernel's host file
//! only says which buffers it binds and how its output is shaped.

use super::buffer::{storage_from, storage_output, submit_and_read, uniform_from};
use super::kernel::Kernel;
use super::GpuBackend;
use crate::abi::SlabParams;
use crate::error::Result;

/// A storage input of a kernel.
pub enum Input<'a> {
    /// Bound whole whatever the slab (e.g. the volume a resample reads from anywhere).
    Whole(&'a str, &'a [f32]),
    /// `per_voxel` floats per voxel of the output grid, bound slab by slab with `halo` extra
    /// slices on each side where the volume has them.
    PerVoxel {
        /// What it is, for error messages.
        what: &'a str,
        /// The values, x fastest.
        data: &'a [f32],
        /// Floats per voxel.
        per_voxel: usize,
        /// Extra slices each side.
        halo: usize,
    },
}

/// Runs `kernel` over an output grid of `dims`, binding the uniform, then `inputs` in order,
/// then the output; the output has `out_per_slice` floats per z-slice. `workgroups` gives the
/// dispatch size for a slab of `depth` slices.
pub fn run_slabs<P: SlabParams>(
    gpu: &GpuBackend,
    kernel: &Kernel,
    params: &P,
    inputs: &[Input],
    dims: [usize; 3],
    out_per_slice: usize,
    workgroups: impl Fn(usize) -> [u32; 3],
) -> Result<Vec<f32>> {
    let ctx = gpu.context();
    let slice = dims[0] * dims[1];
    let halo = inputs
        .iter()
        .map(|i| match i {
            Input::PerVoxel { halo, .. } => *halo,
            Input::Whole(..) => 0,
        })
        .max()
        .unwrap_or(0);
    let bytes_per_voxel = inputs
        .iter()
        .map(|i| match i {
            Input::PerVoxel { per_voxel, .. } => per_voxel * 4,
            Input::Whole(..) => 0,
        })
        .chain([out_per_slice.div_ceil(slice) * 4])
        .max()
        .unwrap_or(4);
    let slabs = gpu.plan_slabs(dims, bytes_per_voxel, 2 * halo)?;
    let whole: Vec<Option<wgpu::Buffer>> = inputs
        .iter()
        .map(|i| match i {
            Input::Whole(what, data) => storage_from(ctx, what, data).map(Some),
            Input::PerVoxel { .. } => Ok(None),
        })
        .collect::<Result<_>>()?;
    let mut out = Vec::with_capacity(out_per_slice * dims[2]);
    for slab in slabs {
        let first = slab.z0.saturating_sub(halo);
        let last = (slab.z0 + slab.depth + halo).min(dims[2]);
        let uniform = uniform_from(
            ctx,
            "kernel parameters",
            &params.for_slab(slab.z0 as u32, slab.depth as u32, first as u32),
        )?;
        let mut buffers = vec![uniform];
        for (input, bound) in inputs.iter().zip(&whole) {
            match (input, bound) {
                (_, Some(buffer)) => buffers.push(buffer.clone()),
                (
                    Input::PerVoxel {
                        what,
                        data,
                        per_voxel,
                        ..
                    },
                    None,
                ) => {
                    let range = first * slice * per_voxel..last * slice * per_voxel;
                    buffers.push(storage_from(ctx, what, &data[range])?);
                }
                (Input::Whole(..), None) => unreachable!("whole inputs are bound above"),
            }
        }
        let len = out_per_slice * slab.depth;
        buffers.push(storage_output::<f32>(ctx, "kernel output", len)?);
        gpu.note_dispatch_bytes(buffers.iter().map(|b| b.size()).sum());
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let refs: Vec<&wgpu::Buffer> = buffers.iter().collect();
        kernel.dispatch(ctx, &mut encoder, &refs, workgroups(slab.depth))?;
        out.extend(submit_and_read::<f32>(
            ctx,
            encoder,
            &buffers[buffers.len() - 1],
            len,
        )?);
    }
    Ok(out)
}
