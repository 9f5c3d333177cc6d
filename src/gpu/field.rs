//! Host side of shaders/warp_field.wgsl and shaders/compose.wgsl: the final field's kernels,
//! slab by slab.

use super::kernel::{groups, Binding};
use super::run::{run_slabs, Input};
use super::GpuBackend;
use crate::abi::{ComposeParams, RbfGradParams};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// warp_field bindings in the order the shader declares them.
pub const WARP_BINDINGS: &[Binding] = &[Uniform, Read, ReadWrite];
/// compose bindings.
pub const COMPOSE_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];

/// The lattice interpolated at every voxel (3 floats per voxel).
pub fn warp_field(gpu: &GpuBackend, params: &RbfGradParams, lattice: &[f32]) -> Result<Vec<f32>> {
    let dims = [0, 1, 2].map(|a| params.dims[a] as usize);
    run_slabs(
        gpu,
        &gpu.kernels.warp_field,
        params,
        &[Input::Whole("warp lattice", lattice)],
        dims,
        dims[0] * dims[1] * 3,
        |depth| [groups(dims[0], 4), groups(dims[1], 4), groups(depth, 4)],
    )
}

/// u = R + u0 ∘ (id + R) (3 floats per voxel).
pub fn compose(
    gpu: &GpuBackend,
    params: &ComposeParams,
    warp: &[f32],
    initial: &[f32],
) -> Result<Vec<f32>> {
    let dims = [0, 1, 2].map(|a| params.dims[a] as usize);
    run_slabs(
        gpu,
        &gpu.kernels.compose,
        params,
        &[
            Input::PerVoxel {
                what: "warp field",
                data: warp,
                per_voxel: 3,
                halo: 0,
            },
            Input::Whole("initial field", initial),
        ],
        dims,
        dims[0] * dims[1] * 3,
        |depth| [groups(dims[0], 4), groups(dims[1], 4), groups(depth, 4)],
    )
}
