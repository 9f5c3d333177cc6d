//! Host side of shaders/rbf_grad.wgsl.

use super::kernel::{groups, Binding};
use super::run::{run_slabs, Input};
use super::GpuBackend;
use crate::abi::RbfGradParams;
use crate::error::Result;

/// rbf_grad bindings in the order the shader declares them.
pub const GRAD_BINDINGS: &[Binding] = &[
    Binding::Uniform,
    Binding::Read,
    Binding::Read,
    Binding::Read,
    Binding::ReadWrite,
];

/// Per-voxel cost terms and gradients.
pub fn rbf_grad(
    gpu: &GpuBackend,
    params: &RbfGradParams,
    lattice: &[f32],
    moving: &[f32],
    fixed: &[f32],
) -> Result<Vec<f32>> {
    let dims = [0, 1, 2].map(|a| params.dims[a] as usize);
    run_slabs(
        gpu,
        &gpu.kernels.rbf_grad,
        params,
        &[
            Input::Whole("warp lattice", lattice),
            Input::Whole("moving image", moving),
            Input::PerVoxel {
                what: "target image",
                data: fixed,
                per_voxel: 1,
                halo: 0,
            },
        ],
        dims,
        dims[0] * dims[1] * 4,
        |depth| [groups(dims[0], 4), groups(dims[1], 4), groups(depth, 4)],
    )
}
