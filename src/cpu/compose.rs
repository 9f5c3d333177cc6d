//! CPU twin of shaders/compose.wgsl.

use super::common::linear_row;
use crate::abi::ComposeParams;
use crate::sample::{affine_row, trilinear_with_gradient};
use rayon::prelude::*;

/// Fills `out` (3 floats per voxel) with u = R + u0 ∘ (id + R), `warp` holding R and
/// `initial` u0 (3 floats per voxel each, u0 on its own grid).
pub fn compose(params: &ComposeParams, warp: &[f32], initial: &[f32], out: &mut [f32]) {
    let [nx, ny, _, _] = params.dims;
    let [ex, ey, ez, _] = params.initial_dims;
    let e = [ex, ey, ez];
    // The shader reads one component at a time through sampled_value; here each is a volume.
    let components: Vec<Vec<f32>> = (0..3)
        .map(|c| initial.iter().skip(c).step_by(3).copied().collect())
        .collect();
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
                    let q: [f32; 3] = std::array::from_fn(|a| {
                        affine_row(params.index_to_initial[a], x)
                            + linear_row(params.mm_to_initial[a], r)
                    });
                    let qc: [f32; 3] = std::array::from_fn(|a| q[a].clamp(0.0, e[a] as f32 - 1.0));
                    for c in 0..3 {
                        slice[o + c] = r[c] + trilinear_with_gradient(&components[c], qc, e)[0];
                    }
                }
            }
        });
}
