//! CPU twin of shaders/nonrigid/ssd_cells.wgsl: the same (x, z)-column partial sums, one slice per
//! rayon task.

use crate::abi::SsdParams;
use crate::backend::CostImages;
use crate::cpu::common::{cell_start, is_covered, voxel_index};
use rayon::prelude::*;

/// Fills `partial` (nz * nx * cy values) with per-column, per-y-cell sums of c (a - b)^2, a the
/// moving image, b the fixed one.
pub fn ssd_cells(params: &SsdParams, images: &CostImages<[f32]>, partial: &mut [f32]) {
    let [nx, ny, nz, _] = params.dims;
    let cy = params.cells[1];
    let dims = [nx, ny, nz];
    let CostImages {
        moving: a,
        fixed: b,
        covered,
    } = *images;
    partial
        .par_chunks_mut((nx * cy) as usize)
        .enumerate()
        .for_each(|(z, out)| {
            let z = z as u32;
            for x in 0..nx {
                for c in 0..cy {
                    let mut sum = 0.0f32;
                    for y in cell_start(c, ny, cy)..cell_start(c + 1, ny, cy) {
                        let i = voxel_index(x, y, z, dims) as usize;
                        let d = if is_covered(covered[i]) {
                            a[i] - b[i]
                        } else {
                            0.0
                        };
                        sum += d * d;
                    }
                    out[(x * cy + c) as usize] = sum;
                }
            }
        });
}
