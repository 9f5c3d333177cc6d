//! CPU twin of shaders/field/fade_warp.wgsl (with shaders/fade.wgsl).

use crate::abi::FadeParams;
use crate::cpu::fade::fade_at;
use rayon::prelude::*;

/// Fills `out` (3 floats per voxel) with `warp` scaled by each voxel's distance to the
/// nearest bone (`distance`, mm) over the margin, clamped to 1; zero on
/// the bones.
pub fn fade_warp(params: &FadeParams, warp: &[f32], distance: &[f32], out: &mut [f32]) {
    out.par_chunks_mut(3).enumerate().for_each(|(v, r)| {
        let scale = fade_at(distance, v, 1, params.margin);
        for c in 0..3 {
            r[c] = scale * warp[3 * v + c];
        }
    });
}
