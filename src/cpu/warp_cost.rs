//! CPU twin of shaders/warp_cost.wgsl.

use super::common::{is_covered, voxel_index};
use super::warp_image::{warped_sample, LatticeTaps};
use crate::abi::RbfGradParams;
use crate::backend::CostImages;
use rayon::prelude::*;

/// Fills `gradient` (3 floats per voxel: c · 2 (W − T) ∇I0, world mm) and `rows` (Σ c (W − T)²
/// per row of x, index j + ny k).
pub fn warp_cost(
    params: &RbfGradParams,
    lattice: &[f32],
    images: &CostImages<[f32]>,
    gradient: &mut [f32],
    rows: &mut [f32],
) {
    let [nx, ny, nz, _] = params.dims;
    let d = [nx, ny, nz];
    let taps = LatticeTaps::new(params);
    gradient
        .par_chunks_mut(3 * nx as usize)
        .zip(rows.par_iter_mut())
        .enumerate()
        .for_each(|(row, (out, sum_out))| {
            let (j, k) = (row as u32 % ny, row as u32 / ny);
            let mut sum = 0.0f32;
            let lattice_row = taps.row(params, lattice, j, k);
            for i in 0..nx {
                let v = voxel_index(i, j, k, d) as usize;
                let t = images.fixed[v];
                let s = warped_sample(params, &lattice_row, &taps, images.moving, [i, j, k], t);
                let c = if is_covered(images.covered[v]) {
                    1.0
                } else {
                    0.0
                };
                let e = s[0] - t;
                sum += c * e * e;
                let g = [s[1], s[2], s[3]];
                let o = 3 * i as usize;
                for a in 0..3 {
                    out[o + a] = c * g[a];
                }
            }
            *sum_out = sum;
        });
}
