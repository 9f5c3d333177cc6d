//! CPU twins of shaders/label_index.wgsl and shaders/bone_at_source.wgsl (their lookups,
//! labels.wgsl and bone_lookup.wgsl, are twinned in crate::sample).

use super::common::{dims3, voxel_index};
use crate::abi::{BoneLookupParams, LabelParams};
use crate::sample::{bone_at, code_index};
use rayon::prelude::*;

/// Fills `index` (1 float per voxel) with each label's code_index.
pub fn label_index(params: &LabelParams, labels: &[f32], index: &mut [f32]) {
    index
        .par_iter_mut()
        .zip(labels.par_iter())
        .for_each(|(out, &label)| *out = code_index(&params.codes, label) as f32);
}

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
                    let found = if residual[v] <= params.limit[0] {
                        bone_at(params, labels, [i as f32, j as f32, k as f32], u)
                    } else {
                        0
                    };
                    slice[(i + nx * j) as usize] = found as f32;
                }
            }
        });
}
