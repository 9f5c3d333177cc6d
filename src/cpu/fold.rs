//! CPU twins of shaders/fold_stats.wgsl, shaders/mark_at_most.wgsl, shaders/dilate.wgsl and
//! shaders/fold_smooth.wgsl.

use super::common::{dims3, voxel_index};
use crate::abi::{BoneLookupParams, DilateParams, ThresholdParams, FOLD_STATS_WIDTH};
use crate::sample::bone_at;
use glam::Vec3;
use rayon::prelude::*;

fn is_held(value: f32) -> bool {
    value > 0.0
}

/// Fills `stats` ([`FOLD_STATS_WIDTH`] floats per chunk) with each chunk's minimum and counts,
/// the voxels at or below the threshold at a bone contact apart.
pub fn fold_stats(params: &ThresholdParams, det: &[f32], held: &[f32], stats: &mut [f32]) {
    let [voxels, per_chunk, _, _] = params.chunks.map(|n| n as usize);
    let threshold = params.threshold[0];
    let dims = dims3(params.dims);
    let count = |yes: bool| if yes { 1.0 } else { 0.0 };
    stats
        .par_chunks_mut(FOLD_STATS_WIDTH)
        .enumerate()
        .for_each(|(c, out)| {
            let (mut lowest, mut folded, mut low, mut low_free) =
                (3.4e38f32, 0.0f32, 0.0f32, 0.0f32);
            let mut contacts = 0.0f32;
            for v in c * per_chunk..((c + 1) * per_chunk).min(voxels) {
                let d = det[v];
                if d <= threshold && is_contact(held, dims, v as u32) {
                    contacts += count(d <= 0.0);
                    continue;
                }
                lowest = lowest.min(d);
                folded += count(d <= 0.0);
                low += count(d <= threshold);
                low_free += count(d <= threshold && !is_held(held[v]));
            }
            out.copy_from_slice(&[lowest, folded, low, low_free, contacts]);
        });
}

/// The voxel one step from `c` along `axis` in direction `step` (−1 or 1), the voxel itself at
/// the volume's faces.
fn face_neighbour(c: [u32; 3], axis: usize, step: i32, dims: [u32; 3]) -> u32 {
    let mut p = c;
    if step < 0 && p[axis] > 0 {
        p[axis] -= 1;
    }
    if step > 0 && p[axis] + 1 < dims[axis] {
        p[axis] += 1;
    }
    voxel_index(p[0], p[1], p[2], dims)
}

/// Whether voxel v is a bone contact (`held` values are bone numbers): along one axis its two
/// stencil neighbours (the voxel itself on a face) held in two different bones, or all six held,
/// in two different bones. Its determinant then takes a difference across the jump from one
/// bone's rigid motion to the other's, or is a function of the bones' motions alone; where they
/// slide on each other it measures the slide.
fn is_contact(held: &[f32], dims: [u32; 3], v: u32) -> bool {
    let c = [
        v % dims[0],
        (v / dims[0]) % dims[1],
        v / (dims[0] * dims[1]),
    ];
    let first = held[face_neighbour(c, 0, -1, dims) as usize];
    let mut all_held = true;
    let mut two_bones = false;
    let mut spans_along_an_axis = false;
    for axis in 0..3 {
        let lo = held[face_neighbour(c, axis, -1, dims) as usize];
        let hi = held[face_neighbour(c, axis, 1, dims) as usize];
        let both_held = is_held(lo) && is_held(hi);
        all_held = all_held && both_held;
        two_bones = two_bones || lo != first || hi != first;
        spans_along_an_axis = spans_along_an_axis || (both_held && lo != hi);
    }
    spans_along_an_axis || (all_held && two_bones)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Affine, Grid};

    /// A row of voxels x = 0..7 with det ≤ 0 at x = 2 and 5: x = 2, in bone 1, lies between
    /// bone 1 (x = 1) and bone 2 (x = 3), a contact (in a row the other axes' neighbours are the
    /// voxel itself); x = 5 has tissue beside it and folds. The statistics count one fold (the
    /// minimum is its determinant) and one contact.
    #[test]
    fn a_stencil_holding_two_bones_is_a_contact_not_a_fold() {
        let grid = Grid::new([8, 1, 1], Affine::identity()).unwrap();
        let det = [1.0, 1.0, -0.5, 1.0, 1.0, -0.25, 1.0, 1.0];
        let held = [0.0, 1.0, 1.0, 2.0, 2.0, 0.0, 0.0, 0.0];
        let params = ThresholdParams::new(&grid, 0.05);
        let mut stats = vec![0.0; FOLD_STATS_WIDTH * params.chunks()];
        fold_stats(&params, &det, &held, &mut stats);
        assert_eq!(stats, [-0.25, 1.0, 1.0, 1.0, 1.0]);
    }

    /// A 5 × 3 slice with det ≤ 0 at (2, 1), tissue between bone 1 (x = 1) and bone 2 (x = 3)
    /// with tissue above and below it: its x difference spans the two bones, a contact though
    /// not every neighbour is held; and at (4, 2), tissue beside bone 2 only, a fold.
    #[test]
    fn a_stencil_spanning_two_bones_along_one_axis_is_a_contact() {
        let grid = Grid::new([5, 3, 1], Affine::identity()).unwrap();
        let mut det = [1.0; 15];
        det[5 + 2] = -2.0;
        det[10 + 4] = -0.5;
        let mut held = [0.0; 15];
        held[5 + 1] = 1.0;
        held[5 + 3] = 2.0;
        held[10 + 3] = 2.0;
        let params = ThresholdParams::new(&grid, 0.05);
        let mut stats = vec![0.0; FOLD_STATS_WIDTH * params.chunks()];
        fold_stats(&params, &det, &held, &mut stats);
        assert_eq!(stats, [-0.5, 1.0, 1.0, 1.0, 1.0]);
    }
}
