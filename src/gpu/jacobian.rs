//! Host side of shaders/jacobian.wgsl.

use super::kernel::{groups, Binding};
use super::run::{run_slabs, Input};
use super::GpuBackend;
use crate::abi::JacobianParams;
use crate::error::Result;

/// Bindings in the order the shader declares them.
pub const BINDINGS: &[Binding] = &[Binding::Uniform, Binding::Read, Binding::ReadWrite];

/// det(I + du/dx) for every voxel; slabs carry one halo slice each side for the differences.
pub fn jacobian(gpu: &GpuBackend, params: &JacobianParams, field: &[f32]) -> Result<Vec<f32>> {
    let dims = [0, 1, 2].map(|a| params.dims[a] as usize);
    run_slabs(
        gpu,
        &gpu.kernels.jacobian,
        params,
        &[Input::PerVoxel {
            what: "displacement field",
            data: field,
            per_voxel: 3,
            halo: 1,
        }],
        dims,
        dims[0] * dims[1],
        |depth| [groups(dims[0], 4), groups(dims[1], 4), groups(depth, 4)],
    )
}
