//! CPU twin of shaders/skinning/skin_weights.wgsl.

use crate::abi::{SkinWeightsParams, MAX_SKIN_BONES};
use rayon::prelude::*;

/// Fills `weight` (bones per voxel) from `distance` (one volume per bone), each bone's
/// distances scaled by its reach.
pub fn skin_weights(params: &SkinWeightsParams, distance: &[f32], weight: &mut [f32]) {
    let bones = params.bones as usize;
    let power = params.power;
    let voxels = weight.len() / bones.max(1);
    let scaled = |j: usize, v: usize| distance[j * voxels + v] * params.reach[j / 4][j % 4];
    weight.par_chunks_mut(bones).enumerate().for_each(|(v, w)| {
        // On the stack (bones ≤ MAX_SKIN_BONES): a Vec here was an allocation per voxel.
        let mut scaled_distances = [0.0f32; MAX_SKIN_BONES];
        for (j, d) in scaled_distances[..bones].iter_mut().enumerate() {
            *d = scaled(j, v);
        }
        let d = &scaled_distances[..bones];
        let inside = d.iter().position(|&dj| dj <= 0.0);
        if let Some(j) = inside {
            for (k, wk) in w.iter_mut().enumerate() {
                *wk = if k == j { 1.0 } else { 0.0 };
            }
            return;
        }
        let nearest = d.iter().fold(d[0], |m, &dj| m.min(dj));
        let mut total = 0.0f32;
        for (wk, dk) in w.iter_mut().zip(d) {
            let ratio = nearest / dk;
            let mut raw = 1.0f32;
            for _ in 0..power {
                raw *= ratio;
            }
            *wk = raw;
            total += raw;
        }
        for wk in w.iter_mut() {
            *wk /= total;
        }
    });
}
