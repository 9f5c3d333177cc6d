//! CPU twin of shaders/resample.wgsl: one target slice per rayon task.

use super::common::{affine_row, linear_row, voxel_index};
use crate::abi::ResampleParams;
use crate::sample::{nearest, trilinear};
use rayon::prelude::*;

/// Fills `warped` (one value per voxel of the slab `params` describes) from `source` and the
/// slab's packed field (3 floats per voxel).
pub fn resample(params: &ResampleParams, source: &[f32], field: &[f32], warped: &mut [f32]) {
    let [nx, ny, _, z0] = params.target_dims;
    let depth = params.source_dims[3];
    let source_dims = [
        params.source_dims[0],
        params.source_dims[1],
        params.source_dims[2],
    ];
    let slice = (nx * ny) as usize;
    warped
        .par_chunks_mut(slice)
        .enumerate()
        .for_each(|(zl, out)| {
            let zl = zl as u32;
            for y in 0..ny {
                for x in 0..nx {
                    let local = voxel_index(x, y, zl, [nx, ny, depth]) as usize;
                    let p = [x as f32, y as f32, (zl + z0) as f32];
                    let u = [field[3 * local], field[3 * local + 1], field[3 * local + 2]];
                    let q: [f32; 3] = std::array::from_fn(|r| {
                        affine_row(params.index_to_source[r], p)
                            + linear_row(params.mm_to_source[r], u)
                    });
                    out[local - zl as usize * slice] = if params.nearest == 1 {
                        nearest(source, q, source_dims, params.background)
                    } else {
                        trilinear(source, q, source_dims, params.background)
                    };
                }
            }
        });
}
