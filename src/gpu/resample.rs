//! Host side of shaders/resample.wgsl.

use super::kernel::{groups, Binding};
use super::run::{run_slabs, Input};
use super::GpuBackend;
use crate::abi::ResampleParams;
use crate::error::Result;

/// Bindings in the order the shader declares them.
pub const BINDINGS: &[Binding] = &[
    Binding::Uniform,
    Binding::Read,
    Binding::Read,
    Binding::ReadWrite,
];

/// Resamples slab by slab; returns the warped values of every target voxel, x fastest.
pub fn resample(
    gpu: &GpuBackend,
    params: &ResampleParams,
    source: &[f32],
    field: &[f32],
) -> Result<Vec<f32>> {
    let dims = [0, 1, 2].map(|a| params.target_dims[a] as usize);
    run_slabs(
        gpu,
        &gpu.kernels.resample,
        params,
        &[
            Input::Whole("source volume", source),
            Input::PerVoxel {
                what: "displacement field",
                data: field,
                per_voxel: 3,
                halo: 0,
            },
        ],
        dims,
        dims[0] * dims[1],
        |depth| [groups(dims[0], 4), groups(dims[1], 4), groups(depth, 4)],
    )
}
