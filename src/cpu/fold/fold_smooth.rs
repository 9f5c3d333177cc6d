//! CPU twin of shaders/fold/fold_smooth.wgsl.

use crate::abi::BoneLookupParams;
use crate::cpu::common::{dims3, voxel_index};
use crate::sample::bone_at;
use glam::Vec3;
use rayon::prelude::*;

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
