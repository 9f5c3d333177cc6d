//! CPU twin of shaders/fade_warp.wgsl (with shaders/fade.wgsl).

use crate::abi::FadeParams;
use rayon::prelude::*;

/// How much of a warp voxel `v` keeps: its distance to the nearest of `bones` bones
/// (`distance`: one volume of `voxels` per bone, mm) over `margin`, clamped to 1; 0 on the
/// bones, 1 without bones (fade_at in shaders/fade.wgsl).
#[inline]
pub fn fade_at(distance: &[f32], v: usize, voxels: usize, bones: usize, margin: f32) -> f32 {
    if bones == 0 {
        return 1.0;
    }
    let nearest = (1..bones).fold(distance[v], |m, b| m.min(distance[b * voxels + v]));
    if nearest <= 0.0 {
        0.0
    } else {
        (nearest / margin).min(1.0)
    }
}

/// Fills `out` (3 floats per voxel) with `warp` scaled by each voxel's distance to the
/// nearest bone (`distance`: one volume per bone, mm) over the margin, clamped to 1; zero on
/// the bones.
pub fn fade_warp(params: &FadeParams, warp: &[f32], distance: &[f32], out: &mut [f32]) {
    let voxels = params.voxels();
    let bones = params.dims[3] as usize;
    out.par_chunks_mut(3).enumerate().for_each(|(v, r)| {
        let scale = fade_at(distance, v, voxels, bones, params.margin[0]);
        for c in 0..3 {
            r[c] = scale * warp[3 * v + c];
        }
    });
}
