//! CPU twin of shaders/rigid/rigid_score.wgsl.

use crate::abi::{ScoreParams, SCORE_SUMS};
use crate::backend::rigid::BoneImages;
use crate::cpu::common::{affine_row, voxel_index};
use crate::sample::{array_from, inside_source, trilinear};
use rayon::prelude::*;

/// Fills `partial` with abi::SCORE_SUMS sums per column and candidate (Σ r², count, Σ S, Σ T,
/// Σ S², Σ T², Σ S·T), layout ((z * nx + x) * candidates + c) * SCORE_SUMS.
pub fn rigid_score(
    params: &ScoreParams,
    images: &BoneImages<[f32]>,
    candidates: &[f32],
    partial: &mut [f32],
) {
    let BoneImages {
        source,
        mask,
        target,
    } = *images;
    let [nx, ny, nz, _] = params.dims;
    let count = params.candidates;
    let tdims = [
        params.target_dims[0],
        params.target_dims[1],
        params.target_dims[2],
    ];
    partial
        .par_chunks_mut(nx as usize * count as usize * SCORE_SUMS)
        .enumerate()
        .for_each(|(z, out)| {
            let z = z as u32;
            for x in 0..nx {
                for c in 0..count {
                    let row = |r: u32| -> [f32; 4] {
                        let b = (c * 12 + r * 4) as usize;
                        [
                            candidates[b],
                            candidates[b + 1],
                            candidates[b + 2],
                            candidates[b + 3],
                        ]
                    };
                    let m = [row(0), row(1), row(2)];
                    // Σr², count, ΣS, ΣT, ΣS², ΣT², ΣST, summed in the shader's order.
                    let mut sums = [0.0f32; SCORE_SUMS];
                    for y in 0..ny {
                        let i = voxel_index(x, y, z, [nx, ny, nz]) as usize;
                        if mask[i] < 0.5 {
                            continue;
                        }
                        let p = [x as f32, y as f32, z as f32];
                        let w: [f32; 3] = array_from(|r| affine_row(params.source_to_world[r], p));
                        let moved: [f32; 3] = array_from(|r| affine_row(m[r], w));
                        let q: [f32; 3] =
                            array_from(|r| affine_row(params.world_to_target[r], moved));
                        if !inside_source(q, tdims) {
                            continue;
                        }
                        let t = trilinear(target, q, tdims, 0.0);
                        let s = source[i];
                        let r = t - s;
                        let terms = [r * r, 1.0, s, t, s * s, t * t, s * t];
                        for (sum, term) in sums.iter_mut().zip(terms) {
                            *sum += term;
                        }
                    }
                    let base = (x * count + c) as usize * SCORE_SUMS;
                    out[base..base + SCORE_SUMS].copy_from_slice(&sums);
                }
            }
        });
}
