//! CPU twin of shaders/labels/bone_at_source.wgsl (its lookups, labels.wgsl and
//! bone_lookup.wgsl, are twinned in crate::sample).

use crate::abi::BoneLookupParams;
use crate::cpu::common::{dims3, voxel_index};
use crate::sample::bone_at;
use rayon::prelude::*;

/// Fills `bone` (1 float per target voxel) with the bone at each voxel's source point, where
/// its residual is within the limit.
pub fn bone_at_source(
    params: &BoneLookupParams,
    field: &[f32],
    residual: &[f32],
    labels: &[f32],
    bone: &mut [f32],
) {
    let dims = dims3(params.geometry.target_dims);
    let [nx, ny, _] = dims;
    bone.par_chunks_mut((nx * ny) as usize)
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..ny {
                for i in 0..nx {
                    let v = voxel_index(i, j, k as u32, dims) as usize;
                    let u = [field[3 * v], field[3 * v + 1], field[3 * v + 2]];
                    let found = if residual[v] <= params.limit {
                        bone_at(params, labels, [i as f32, j as f32, k as f32], u)
                    } else {
                        0
                    };
                    slice[(i + nx * j) as usize] = found as f32;
                }
            }
        });
}
