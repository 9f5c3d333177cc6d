//! Host side of shaders/rigid_gn.wgsl and shaders/rigid_score.wgsl.

use super::kernel::{groups, Binding};
use super::run::{run_slabs, Input};
use super::GpuBackend;
use crate::abi::RIGID_SUMS as SUMS;
use crate::abi::{RigidParams, ScoreParams};
use crate::error::Result;

/// rigid_gn bindings in the order the shader declares them.
pub const GN_BINDINGS: &[Binding] = &[
    Binding::Uniform,
    Binding::Read,
    Binding::Read,
    Binding::Read,
    Binding::ReadWrite,
];

/// rigid_score bindings in the order the shader declares them.
pub const SCORE_BINDINGS: &[Binding] = &[
    Binding::Uniform,
    Binding::Read,
    Binding::Read,
    Binding::Read,
    Binding::Read,
    Binding::ReadWrite,
];

fn per_voxel<'a>(what: &'a str, data: &'a [f32]) -> Input<'a> {
    Input::PerVoxel {
        what,
        data,
        per_voxel: 1,
        halo: 0,
    }
}

/// Gauss-Newton column sums.
pub fn rigid_sums(
    gpu: &GpuBackend,
    params: &RigidParams,
    source: &[f32],
    mask: &[f32],
    target: &[f32],
) -> Result<Vec<f32>> {
    let dims = [0, 1, 2].map(|a| params.dims[a] as usize);
    run_slabs(
        gpu,
        &gpu.kernels.rigid_gn,
        params,
        &[
            per_voxel("source", source),
            per_voxel("bone mask", mask),
            Input::Whole("target", target),
        ],
        dims,
        dims[0] * SUMS,
        |depth| [groups(dims[0], 64), depth as u32, 1],
    )
}

/// Candidate scores.
pub fn rigid_scores(
    gpu: &GpuBackend,
    params: &ScoreParams,
    source: &[f32],
    mask: &[f32],
    target: &[f32],
    candidates: &[f32],
) -> Result<Vec<f32>> {
    let dims = [0, 1, 2].map(|a| params.dims[a] as usize);
    let count = params.slab[1];
    run_slabs(
        gpu,
        &gpu.kernels.rigid_score,
        params,
        &[
            per_voxel("source", source),
            per_voxel("bone mask", mask),
            Input::Whole("target", target),
            Input::Whole("candidate motions", candidates),
        ],
        dims,
        dims[0] * count as usize * 2,
        |depth| [groups(dims[0], 64), depth as u32, count],
    )
}
