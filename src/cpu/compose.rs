//! CPU twin of shaders/compose.wgsl.

use super::common::linear_row;
use crate::abi::ComposeParams;
use crate::sample::trilinear_with_gradient;
use rayon::prelude::*;

/// Fills `out` (3 floats per voxel) with u = R + u0 ∘ (id + R), `warp` holding R and
/// `initial` u0 (3 floats per voxel each).
pub fn compose(params: &ComposeParams, warp: &[f32], initial: &[f32], out: &mut [f32]) {
    let [nx, ny, nz, _] = params.dims;
    let d = [nx, ny, nz];
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
                    let q = [
                        i as f32 + linear_row(params.mm_to_index[0], r),
                        j as f32 + linear_row(params.mm_to_index[1], r),
                        k as f32 + linear_row(params.mm_to_index[2], r),
                    ];
                    let qc: [f32; 3] = std::array::from_fn(|a| q[a].clamp(0.0, d[a] as f32 - 1.0));
                    for c in 0..3 {
                        slice[o + c] = r[c] + trilinear_with_gradient(&components[c], qc, d)[0];
                    }
                }
            }
        });
}
