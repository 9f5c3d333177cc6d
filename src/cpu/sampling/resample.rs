//! CPU twin of shaders/sampling/resample.wgsl: one target slice per rayon task.

use crate::abi::ResampleParams;
use crate::cpu::common::{source_index, voxel_index};
use crate::sample::{nearest, trilinear};
use rayon::prelude::*;

/// Fills `warped` (one value per target voxel) from `source` and the packed field (3 floats
/// per target voxel).
pub fn resample(params: &ResampleParams, source: &[f32], field: &[f32], warped: &mut [f32]) {
    let [nx, ny, nz, _] = params.target_dims;
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
                    let local = voxel_index(x, y, zl, [nx, ny, nz]) as usize;
                    let p = [x as f32, y as f32, zl as f32];
                    let u = [field[3 * local], field[3 * local + 1], field[3 * local + 2]];
                    let q = source_index(params, p, u);
                    out[local - zl as usize * slice] = if params.nearest == 1 {
                        nearest(source, q, source_dims, params.background)
                    } else {
                        trilinear(source, q, source_dims, params.background)
                    };
                }
            }
        });
}
