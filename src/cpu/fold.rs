//! CPU twins of shaders/fold_stats.wgsl, shaders/mark_at_most.wgsl, shaders/dilate.wgsl and
//! shaders/fold_smooth.wgsl.

use super::common::{dims3, voxel_index};
use crate::abi::{BoneLookupParams, DilateParams, ThresholdParams};
use crate::sample::bone_at;
use glam::Vec3;
use rayon::prelude::*;

fn is_held(value: f32) -> bool {
    value > 0.0
}

/// Fills `stats` (4 floats per chunk) with each chunk's minimum and counts.
pub fn fold_stats(params: &ThresholdParams, det: &[f32], held: &[f32], stats: &mut [f32]) {
    let [voxels, per_chunk, _, _] = params.chunks.map(|n| n as usize);
    let threshold = params.threshold[0];
    stats.par_chunks_mut(4).enumerate().for_each(|(c, out)| {
        let (mut lowest, mut folded, mut low, mut low_free) = (3.4e38f32, 0.0f32, 0.0f32, 0.0f32);
        for v in c * per_chunk..((c + 1) * per_chunk).min(voxels) {
            let d = det[v];
            lowest = lowest.min(d);
            folded += if d <= 0.0 { 1.0 } else { 0.0 };
            low += if d <= threshold { 1.0 } else { 0.0 };
            low_free += if d <= threshold && !is_held(held[v]) {
                1.0
            } else {
                0.0
            };
        }
        out.copy_from_slice(&[lowest, folded, low, low_free]);
    });
}

/// Fills `mark` (1 float per voxel) with 1 on the voxels not held whose value is at most the
/// threshold.
pub fn mark_at_most(params: &ThresholdParams, value: &[f32], held: &[f32], mark: &mut [f32]) {
    let threshold = params.threshold[0];
    mark.par_iter_mut().enumerate().for_each(|(v, out)| {
        *out = if value[v] <= threshold && !is_held(held[v]) {
            1.0
        } else {
            0.0
        };
    });
}

/// Fills `out` (1 float per voxel) with one axis of a box dilation of `mask`.
pub fn dilate(params: &DilateParams, mask: &[f32], held: &[f32], out: &mut [f32]) {
    let d = dims3(params.dims);
    let (axis, m) = (params.axis[0] as usize, params.dims[3]);
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
                    let cleared = params.axis[1] == 1 && held[v] > 0.0;
                    slice[(i + d[0] * j) as usize] = if near && !cleared { 1.0 } else { 0.0 };
                }
            }
        });
}

/// Fills `out` (3 floats per target voxel) with one sweep of smoothing over `region`.
pub fn fold_smooth(
    params: &BoneLookupParams,
    field: &[f32],
    region: &[f32],
    labels: &[f32],
    out: &mut [f32],
) {
    let d = dims3(params.geometry.target_dims);
    let displacement = |v: usize| Vec3::new(field[3 * v], field[3 * v + 1], field[3 * v + 2]);
    out.par_chunks_mut(3 * (d[0] * d[1]) as usize)
        .enumerate()
        .for_each(|(k, slice)| {
            let k = k as u32;
            for j in 0..d[1] {
                for i in 0..d[0] {
                    let v = voxel_index(i, j, k, d) as usize;
                    let before = displacement(v);
                    let mut after = before;
                    if region[v] > 0.0 {
                        let c = [i, j, k];
                        let lo = c.map(|x| x.max(1) - 1);
                        let hi: [u32; 3] = std::array::from_fn(|a| (c[a] + 2).min(d[a]));
                        let mut sum = Vec3::ZERO;
                        let mut count = 0.0f32;
                        for z in lo[2]..hi[2] {
                            for y in lo[1]..hi[1] {
                                for x in lo[0]..hi[0] {
                                    sum += displacement(voxel_index(x, y, z, d) as usize);
                                    count += 1.0;
                                }
                            }
                        }
                        let smoothed = sum / count;
                        let p = [i as f32, j as f32, k as f32];
                        if bone_at(params, labels, p, smoothed.to_array()) == 0
                            || bone_at(params, labels, p, before.to_array()) != 0
                        {
                            after = smoothed;
                        }
                    }
                    let o = 3 * (i + d[0] * j) as usize;
                    slice[o..o + 3].copy_from_slice(&after.to_array());
                }
            }
        });
}
