//! Host side of shaders/skin_weights.wgsl and shaders/skin_blend.wgsl.

use super::kernel::{groups, Binding};
use super::run::{run_slabs, Input};
use super::GpuBackend;
use crate::abi::{SkinBlendParams, SkinWeightsParams};
use crate::error::Result;

/// skin_weights bindings in the order the shader declares them.
pub const WEIGHTS_BINDINGS: &[Binding] = &[Binding::Uniform, Binding::Read, Binding::ReadWrite];
/// skin_blend bindings in the order the shader declares them.
pub const BLEND_BINDINGS: &[Binding] = &[
    Binding::Uniform,
    Binding::Read,
    Binding::Read,
    Binding::ReadWrite,
];

/// Weights from distances.
pub fn skin_weights(
    gpu: &GpuBackend,
    params: &SkinWeightsParams,
    distances: &[f32],
) -> Result<Vec<f32>> {
    let dims = [0, 1, 2].map(|a| params.dims[a] as usize);
    let bones = params.slab[1] as usize;
    run_slabs(
        gpu,
        &gpu.kernels.skin_weights,
        params,
        &[Input::PerVoxel {
            what: "bone distance maps",
            data: distances,
            per_voxel: bones,
            halo: 0,
        }],
        dims,
        dims[0] * dims[1] * bones,
        |depth| [groups(dims[0], 4), groups(dims[1], 4), groups(depth, 4)],
    )
}

/// The inverted blend: 4 floats per target voxel.
pub fn skin_blend(
    gpu: &GpuBackend,
    params: &SkinBlendParams,
    weights: &[f32],
    bone_of_voxel: &[f32],
) -> Result<Vec<f32>> {
    let dims = [0, 1, 2].map(|a| params.dims[a] as usize);
    run_slabs(
        gpu,
        &gpu.kernels.skin_blend,
        params,
        &[
            Input::Whole("skinning weights", weights),
            Input::Whole("source bone labels", bone_of_voxel),
        ],
        dims,
        dims[0] * dims[1] * 4,
        |depth| [groups(dims[0], 4), groups(dims[1], 4), groups(depth, 4)],
    )
}
