//! CPU twin of shaders/field/compose.wgsl.

use crate::abi::ComposeParams;
use crate::cpu::common::linear_row;
use crate::sample::{affine_row, array_from, blend_corners, corner_indices};
use rayon::prelude::*;

/// Fills `out` (3 floats per voxel) with u = R + u0 ∘ (id + R), `warp` holding R and
/// `initial` u0 (3 floats per voxel each, u0 on its own grid).
pub fn compose(params: &ComposeParams, warp: &[f32], initial: &[f32], out: &mut [f32]) {
    let [nx, ny, _, _] = params.dims;
    let [ex, ey, ez, _] = params.initial_dims;
    let e = [ex, ey, ez];
    out.par_chunks_mut(3 * (nx * ny) as usize)
        .enumerate()
        .for_each(|(zl, slice)| {
            let k = zl as u32;
            for j in 0..ny {
                for i in 0..nx {
                    let o = 3 * (i + nx * j) as usize;
                    let at = 3 * (nx * ny) as usize * zl + o;
                    let r = [warp[at], warp[at + 1], warp[at + 2]];
                    let x = [i as f32, j as f32, k as f32];
                    let mut qc = [0.0f32; 3];
                    for a in 0..3 {
                        let q = affine_row(params.index_to_initial[a], x)
                            + linear_row(params.mm_to_initial[a], r);
                        qc[a] = q.clamp(0.0, e[a] as f32 - 1.0);
                    }
                    // The shader samples each component through sampled_value; the three
                    // share one cell, found once here.
                    let (corners, t) = corner_indices(qc, e);
                    for c in 0..3 {
                        let v = array_from(|n| initial[3 * corners[n] as usize + c]);
                        slice[o + c] = r[c] + blend_corners(v, t)[0];
                    }
                }
            }
        });
}
