//! CPU twin of shaders/sampling/coverage.wgsl.

use crate::abi::ResampleParams;
use crate::cpu::common::{dims3, source_index, voxel_index};
use crate::sample::inside_source;
use rayon::prelude::*;

/// Fills `covered` (1 float per target voxel) with 1 where the voxel's source point lies inside
/// the source and the voxel in `mask` (> 0), else 0.
pub fn coverage(params: &ResampleParams, field: &[f32], mask: &[f32], covered: &mut [f32]) {
    let dims = dims3(params.target_dims);
    let [nx, ny, _] = dims;
    covered
        .par_chunks_mut((nx * ny) as usize)
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..ny {
                for i in 0..nx {
                    let v = voxel_index(i, j, k as u32, dims) as usize;
                    let u = [field[3 * v], field[3 * v + 1], field[3 * v + 2]];
                    let q = source_index(params, [i as f32, j as f32, k as f32], u);
                    let inside = inside_source(q, dims3(params.source_dims)) && mask[v] > 0.0;
                    slice[(i + nx * j) as usize] = if inside { 1.0 } else { 0.0 };
                }
            }
        });
}
