//! CPU twin of shaders/fold/fold_stats.wgsl.

use super::contacts::is_contact;
use super::threshold::is_held;
use crate::abi::{ThresholdParams, FOLD_STATS_WIDTH};
use crate::cpu::common::dims3;
use rayon::prelude::*;

/// Fills `stats` ([`FOLD_STATS_WIDTH`] floats per chunk) with each chunk's minimum and counts,
/// the voxels at or below the threshold at a bone contact apart.
pub fn fold_stats(params: &ThresholdParams, det: &[f32], held: &[f32], stats: &mut [f32]) {
    let [voxels, per_chunk, _, _] = params.chunks.map(|n| n as usize);
    let threshold = params.threshold;
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
