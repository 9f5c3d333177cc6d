//! CPU twin of shaders/warp_cost.wgsl.

use super::common::{linear_row, voxel_index};
use super::rbf_grad::warp_at;
use crate::abi::RbfGradParams;
use crate::backend::CostImages;
use crate::sample::{inside_source, trilinear_with_gradient};
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
    gradient
        .par_chunks_mut(3 * nx as usize)
        .zip(rows.par_iter_mut())
        .enumerate()
        .for_each(|(row, (out, sum_out))| {
            let (j, k) = (row as u32 % ny, row as u32 / ny);
            let mut sum = 0.0f32;
            for i in 0..nx {
                let v = voxel_index(i, j, k, d) as usize;
                let r = warp_at(params, lattice, i, j, k).to_array();
                let q = [
                    i as f32 + linear_row(params.mm_to_index[0], r),
                    j as f32 + linear_row(params.mm_to_index[1], r),
                    k as f32 + linear_row(params.mm_to_index[2], r),
                ];
                let c = images.covered[v];
                let (mut w, mut g) = (0.0f32, [0.0f32; 3]);
                if inside_source(q, d) {
                    let vg = trilinear_with_gradient(images.moving, q, d);
                    let residual = 2.0 * (vg[0] - images.fixed[v]);
                    w = vg[0];
                    g = std::array::from_fn(|a| {
                        residual * linear_row(params.gradient_to_world[a], [vg[1], vg[2], vg[3]])
                    });
                }
                let e = w - images.fixed[v];
                sum += c * e * e;
                let o = 3 * i as usize;
                for a in 0..3 {
                    out[o + a] = c * g[a];
                }
            }
            *sum_out = sum;
        });
}
