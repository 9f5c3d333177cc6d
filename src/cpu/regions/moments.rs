//! CPU twin of shaders/regions/moments.wgsl.

use crate::abi::MomentsParams;
use crate::cpu::common::affine_row;
use rayon::prelude::*;

/// Fills `moments` (4 per chunk: count, Σx, Σy, Σz) over the voxels at or above the threshold.
pub fn moments(params: &MomentsParams, values: &[f32], moments: &mut [f64]) {
    let [voxels, per_chunk, _, _] = params.chunks.map(|n| n as usize);
    let [nx, ny, _, _] = params.dims.map(|n| n as usize);
    moments.par_chunks_mut(4).enumerate().for_each(|(c, out)| {
        let (mut count, mut sum) = (0.0f64, [0.0f64; 3]);
        let chunk = c * per_chunk..((c + 1) * per_chunk).min(voxels);
        for (v, &value) in values[chunk.clone()].iter().enumerate() {
            let v = chunk.start + v;
            if value >= params.threshold {
                let p = [
                    (v % nx) as f32,
                    ((v / nx) % ny) as f32,
                    (v / (nx * ny)) as f32,
                ];
                count += 1.0;
                for (r, s) in sum.iter_mut().enumerate() {
                    *s += affine_row(params.index_to_world[r], p) as f64;
                }
            }
        }
        out.copy_from_slice(&[count, sum[0], sum[1], sum[2]]);
    });
}
