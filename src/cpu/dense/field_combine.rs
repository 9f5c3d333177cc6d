//! CPU twin of shaders/dense/field_combine.wgsl.

use crate::abi::dense::CombineParams;
use crate::cpu::fade::fade_at;
use rayon::prelude::*;

/// Fills `out` (3 floats per voxel) with fade · (a_scale · a + b_scale · b).
pub fn field_combine(
    params: &CombineParams,
    a: &[f32],
    b: &[f32],
    distance: &[f32],
    out: &mut [f32],
) {
    out.par_chunks_mut(3).enumerate().for_each(|(v, r)| {
        let fade = fade_at(distance, v, params.faded, params.margin_mm);
        for c in 0..3 {
            r[c] = fade * (params.a_scale * a[3 * v + c] + params.b_scale * b[3 * v + c]);
        }
    });
}
