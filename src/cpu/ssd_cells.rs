//! CPU twin of shaders/ssd_cells.wgsl: the same (x, z)-column partial sums, one slice per
//! rayon task.

use super::common::{cell_start, voxel_index};
use crate::abi::SsdParams;
use rayon::prelude::*;

/// Fills `partial` (depth * nx * cy values) with per-column, per-y-cell sums of (a - b)^2.
pub fn ssd_cells(params: &SsdParams, a: &[f32], b: &[f32], partial: &mut [f32]) {
    let [nx, ny, depth, _] = params.dims;
    let cy = params.cells[1];
    let dims = [nx, ny, depth];
    partial
        .par_chunks_mut((nx * cy) as usize)
        .enumerate()
        .for_each(|(zl, out)| {
            let zl = zl as u32;
            for x in 0..nx {
                for c in 0..cy {
                    let mut sum = 0.0f32;
                    for y in cell_start(c, ny, cy)..cell_start(c + 1, ny, cy) {
                        let i = voxel_index(x, y, zl, dims) as usize;
                        let d = a[i] - b[i];
                        sum += d * d;
                    }
                    out[(x * cy + c) as usize] = sum;
                }
            }
        });
}
