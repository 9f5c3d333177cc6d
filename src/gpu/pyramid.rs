//! Host side of shaders/pyramid.wgsl.

use super::kernel::{groups, Binding};
use super::run::{run_slabs, Input};
use super::GpuBackend;
use crate::abi::PyramidParams;
use crate::error::Result;

/// Bindings in the order the shader declares them.
pub const BINDINGS: &[Binding] = &[Binding::Uniform, Binding::Read, Binding::ReadWrite];

/// One coarser level.
pub fn pyramid(gpu: &GpuBackend, params: &PyramidParams, input: &[f32]) -> Result<Vec<f32>> {
    let dims = [0, 1, 2].map(|a| params.dims[a] as usize);
    run_slabs(
        gpu,
        &gpu.kernels.pyramid,
        params,
        &[Input::Whole("finer pyramid level", input)],
        dims,
        dims[0] * dims[1],
        |depth| [groups(dims[0], 4), groups(dims[1], 4), groups(depth, 4)],
    )
}
