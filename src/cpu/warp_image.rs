//! CPU twin of shaders/warp_image.wgsl, with the lattice warp and the warped sample it shares
//! with the cost's twins (shaders/lattice_warp.wgsl, shaders/warp_sample.wgsl).

use super::common::{linear_row, voxel_index};
use crate::abi::RbfGradParams;
use crate::sample::{inside_source, trilinear_with_gradient};
use glam::Vec3;
use rayon::prelude::*;

fn node(params: &RbfGradParams, lattice: &[f32], i: u32, j: u32, k: u32) -> Vec3 {
    let l = [
        params.lattice_dims[0],
        params.lattice_dims[1],
        params.lattice_dims[2],
    ];
    let n = 3 * voxel_index(i, j, k, l) as usize;
    Vec3::new(lattice[n], lattice[n + 1], lattice[n + 2])
}

/// Trilinear interpolation of the lattice at voxel (i, j, k).
pub fn warp_at(params: &RbfGradParams, lattice: &[f32], i: u32, j: u32, k: u32) -> Vec3 {
    let s = params.dims[3];
    let top = [
        params.lattice_dims[0] - 1,
        params.lattice_dims[1] - 1,
        params.lattice_dims[2] - 1,
    ];
    let c = [i, j, k];
    let i0: [u32; 3] = std::array::from_fn(|a| (c[a] / s).min(top[a]));
    let i1: [u32; 3] = std::array::from_fn(|a| (i0[a] + 1).min(top[a]));
    let t: [f32; 3] = std::array::from_fn(|a| (c[a] - i0[a] * s) as f32 / s as f32);
    let n = |x, y, z| node(params, lattice, x, y, z);
    let c00 = (1.0 - t[0]) * n(i0[0], i0[1], i0[2]) + t[0] * n(i1[0], i0[1], i0[2]);
    let c10 = (1.0 - t[0]) * n(i0[0], i1[1], i0[2]) + t[0] * n(i1[0], i1[1], i0[2]);
    let c01 = (1.0 - t[0]) * n(i0[0], i0[1], i1[2]) + t[0] * n(i1[0], i0[1], i1[2]);
    let c11 = (1.0 - t[0]) * n(i0[0], i1[1], i1[2]) + t[0] * n(i1[0], i1[1], i1[2]);
    let c0 = (1.0 - t[1]) * c00 + t[1] * c10;
    let c1 = (1.0 - t[1]) * c01 + t[1] * c11;
    (1.0 - t[2]) * c0 + t[2] * c1
}

/// (W, ∂(W − t)²/∂R) at voxel (i, j, k) of `moving` through the warp `lattice`, against the
/// target value `t`; all zero outside (warped_sample in shaders/warp_sample.wgsl).
pub fn warped_sample(
    params: &RbfGradParams,
    lattice: &[f32],
    moving: &[f32],
    [i, j, k]: [u32; 3],
    t: f32,
) -> [f32; 4] {
    let d = [params.dims[0], params.dims[1], params.dims[2]];
    let r = warp_at(params, lattice, i, j, k).to_array();
    let q = [
        i as f32 + linear_row(params.mm_to_index[0], r),
        j as f32 + linear_row(params.mm_to_index[1], r),
        k as f32 + linear_row(params.mm_to_index[2], r),
    ];
    if !inside_source(q, d) {
        return [0.0; 4];
    }
    let vg = trilinear_with_gradient(moving, q, d);
    let g = [vg[1], vg[2], vg[3]];
    let residual = 2.0 * (vg[0] - t);
    [
        vg[0],
        residual * linear_row(params.gradient_to_world[0], g),
        residual * linear_row(params.gradient_to_world[1], g),
        residual * linear_row(params.gradient_to_world[2], g),
    ]
}

/// Fills `warped` (one per voxel) with `moving` seen through the warp `lattice`.
pub fn warp_image(params: &RbfGradParams, lattice: &[f32], moving: &[f32], warped: &mut [f32]) {
    let [nx, ny, _, _] = params.dims;
    warped
        .par_chunks_mut((nx * ny) as usize)
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..ny {
                for i in 0..nx {
                    slice[(i + nx * j) as usize] =
                        warped_sample(params, lattice, moving, [i, j, k as u32], 0.0)[0];
                }
            }
        });
}
