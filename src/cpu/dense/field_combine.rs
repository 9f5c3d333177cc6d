//! CPU twin of shaders/dense/field_combine.wgsl, a block of voxels per rayon task.

use crate::abi::dense::CombineParams;
use crate::cpu::fade::fade_at;
use rayon::prelude::*;

/// Voxels per rayon task: enough that a task's work outweighs handing it out.
const BLOCK: usize = 4096;

/// Fills `out` (3 floats per voxel) with fade · (a_scale · a + b_scale · b).
pub fn field_combine(
    params: &CombineParams,
    a: &[f32],
    b: &[f32],
    distance: &[f32],
    out: &mut [f32],
) {
    out.par_chunks_mut(3 * BLOCK)
        .enumerate()
        .for_each(|(block, out)| {
            let first = block * BLOCK;
            let (a, b) = (&a[3 * first..][..out.len()], &b[3 * first..][..out.len()]);
            combine_block(params, (a, b), (distance, first), out);
        });
}

/// One block of voxels, the first of them voxel `first` (its index in `distance`). Also
/// compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn combine_block(
    params: &CombineParams,
    (a, b): (&[f32], &[f32]),
    (distance, first): (&[f32], usize),
    out: &mut [f32],
) {
    let (a_scale, b_scale) = (params.a_scale, params.b_scale);
    let voxels = out
        .chunks_exact_mut(3)
        .zip(a.chunks_exact(3).zip(b.chunks_exact(3)));
    for (v, (r, (a, b))) in voxels.enumerate() {
        let fade = fade_at(distance, first + v, params.faded, params.margin_mm);
        for c in 0..3 {
            r[c] = fade * (a_scale * a[c] + b_scale * b[c]);
        }
    }
}
