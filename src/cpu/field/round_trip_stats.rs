//! CPU twin of shaders/field/round_trip_stats.wgsl.

use crate::abi::{RoundTripParams, ROUND_TRIP_WIDTH};
use rayon::prelude::*;

/// Fills `stats` ([`ROUND_TRIP_WIDTH`] values per chunk) with each chunk's sum and largest
/// residual over the body's voxels with a preimage, their count, those beyond `far`, and the
/// count without a preimage.
pub fn round_trip_stats(
    params: &RoundTripParams,
    residual: &[f32],
    source: &[f32],
    stats: &mut [f64],
) {
    let [voxels, per_chunk, _, _] = params.counts.map(|n| n as usize);
    stats
        .par_chunks_mut(ROUND_TRIP_WIDTH)
        .enumerate()
        .for_each(|(c, out)| {
            let (mut sum, mut largest, mut with, mut far, mut without) =
                (0.0f64, 0.0f64, 0.0, 0.0, 0.0);
            for v in c * per_chunk..((c + 1) * per_chunk).min(voxels) {
                if source[v] <= 0.0 {
                    continue;
                }
                let r = residual[v];
                if r < 0.0 {
                    without += 1.0;
                    continue;
                }
                sum += r as f64;
                largest = largest.max(r as f64);
                with += 1.0;
                far += if r > params.far { 1.0 } else { 0.0 };
            }
            out.copy_from_slice(&[sum, largest, with, far, without]);
        });
}
