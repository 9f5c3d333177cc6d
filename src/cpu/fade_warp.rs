//! CPU twin of shaders/fade_warp.wgsl.

use crate::abi::FadeParams;
use rayon::prelude::*;

/// Fills `out` (3 floats per voxel) with `warp` scaled by each voxel's distance to the
/// nearest bone (`distance`: one volume per bone, mm) over the margin, clamped to 1; zero on
/// the bones.
pub fn fade_warp(params: &FadeParams, warp: &[f32], distance: &[f32], out: &mut [f32]) {
    let voxels = params.voxels();
    let bones = params.dims[3] as usize;
    out.par_chunks_mut(3).enumerate().for_each(|(v, r)| {
        let nearest = (1..bones).fold(distance[v], |m, b| m.min(distance[b * voxels + v]));
        let scale = if nearest <= 0.0 {
            0.0
        } else {
            (nearest / params.margin[0]).min(1.0)
        };
        for c in 0..3 {
            r[c] = scale * warp[3 * v + c];
        }
    });
}
