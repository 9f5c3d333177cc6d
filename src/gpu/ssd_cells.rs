//! Host side of shaders/ssd_cells.wgsl.

use super::kernel::{groups, Binding};
use super::run::{run_slabs, Input};
use super::GpuBackend;
use crate::abi::SsdParams;
use crate::error::Result;

/// Bindings in the order the shader declares them.
pub const BINDINGS: &[Binding] = &[
    Binding::Uniform,
    Binding::Read,
    Binding::Read,
    Binding::ReadWrite,
];

/// Column partial sums for the whole volume (layout of metric::fold_ssd_partials).
pub fn ssd_partials(
    gpu: &GpuBackend,
    dims: [usize; 3],
    cells: [usize; 3],
    a: &[f32],
    b: &[f32],
) -> Result<Vec<f32>> {
    let per_voxel = |what, data| Input::PerVoxel {
        what,
        data,
        per_voxel: 1,
        halo: 0,
    };
    run_slabs(
        gpu,
        &gpu.kernels.ssd_cells,
        &SsdParams::new(dims, cells, dims[2]),
        &[
            per_voxel("ssd first volume", a),
            per_voxel("ssd second volume", b),
        ],
        dims,
        dims[0] * cells[1],
        |depth| [groups(dims[0], 64), depth as u32, 1],
    )
}
