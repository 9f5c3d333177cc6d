//! CPU twin of shaders/fold/dilate.wgsl.

use crate::abi::DilateParams;
use crate::cpu::common::{dims3, voxel_index};
use rayon::prelude::*;

/// Fills `out` (1 float per voxel) with one axis of a box dilation of `mask`.
pub fn dilate(params: &DilateParams, mask: &[f32], held: &[f32], out: &mut [f32]) {
    let d = dims3(params.dims);
    let (axis, m) = (params.axis as usize, params.margin);
    // Whether each z slice marks any voxel: a slice with none within reach is all zeros, found
    // without looking at its voxels (most of the volume, around a few folds).
    let slice_len = (d[0] * d[1]) as usize;
    let marked: Vec<bool> = mask
        .par_chunks(slice_len)
        .map(|slice| slice.iter().any(|&x| x > 0.0))
        .collect();
    out.par_chunks_mut(slice_len)
        .enumerate()
        .for_each(|(k, slice)| {
            let reach = match axis {
                2 => k.saturating_sub(m as usize)..(k + m as usize + 1).min(d[2] as usize),
                _ => k..k + 1,
            };
            if !marked[reach].contains(&true) {
                slice.fill(0.0);
                return;
            }
            for j in 0..d[1] {
                for i in 0..d[0] {
                    let mut p = [i, j, k as u32];
                    let c = p[axis];
                    let (lo, hi) = (c.max(m) - m, (c + m + 1).min(d[axis]));
                    let near = (lo..hi).any(|a| {
                        p[axis] = a;
                        mask[voxel_index(p[0], p[1], p[2], d) as usize] > 0.0
                    });
                    let v = voxel_index(i, j, k as u32, d) as usize;
                    let cleared = params.clear_held == 1 && held[v] > 0.0;
                    slice[(i + d[0] * j) as usize] = if near && !cleared { 1.0 } else { 0.0 };
                }
            }
        });
}
