//! CPU twin of shaders/warp_image.wgsl, with the lattice warp and the warped sample it shares
//! with the cost's twins (shaders/lattice_warp.wgsl, shaders/warp_sample.wgsl).

use super::common::{linear_row, voxel_index};
use crate::abi::RbfGradParams;
use crate::sample::{inside_source, trilinear_with_gradient};
use glam::Vec3;
use rayon::prelude::*;

#[inline]
fn node(params: &RbfGradParams, lattice: &[f32], i: u32, j: u32, k: u32) -> Vec3 {
    let l = [
        params.lattice_dims[0],
        params.lattice_dims[1],
        params.lattice_dims[2],
    ];
    let n = 3 * voxel_index(i, j, k, l) as usize;
    Vec3::new(lattice[n], lattice[n + 1], lattice[n + 2])
}

/// Where each voxel coordinate falls between lattice nodes, per axis: the shader's (i0, i1, t)
/// for coordinate c at [a][c]. Computed once per call: per voxel, its three integer divisions
/// cost as much as the rest of the interpolation.
pub struct LatticeTaps {
    axes: [Vec<([u32; 2], f32)>; 3],
}

impl LatticeTaps {
    /// The taps of every voxel coordinate of `params`' grid.
    pub fn new(params: &RbfGradParams) -> Self {
        let s = params.dims[3];
        LatticeTaps {
            axes: std::array::from_fn(|a| {
                let top = params.lattice_dims[a] - 1;
                (0..params.dims[a])
                    .map(|c| {
                        let i0 = (c / s).min(top);
                        let i1 = (i0 + 1).min(top);
                        ([i0, i1], (c - i0 * s) as f32 / s as f32)
                    })
                    .collect()
            }),
        }
    }
}

/// Trilinear interpolation of the lattice at voxel (i, j, k).
#[inline]
pub fn warp_at(params: &RbfGradParams, lattice: &[f32], taps: &LatticeTaps, c: [u32; 3]) -> Vec3 {
    let [(x, tx), (y, ty), (z, tz)] = [0, 1, 2].map(|a| taps.axes[a][c[a] as usize]);
    let n = |x, y, z| node(params, lattice, x, y, z);
    let c00 = (1.0 - tx) * n(x[0], y[0], z[0]) + tx * n(x[1], y[0], z[0]);
    let c10 = (1.0 - tx) * n(x[0], y[1], z[0]) + tx * n(x[1], y[1], z[0]);
    let c01 = (1.0 - tx) * n(x[0], y[0], z[1]) + tx * n(x[1], y[0], z[1]);
    let c11 = (1.0 - tx) * n(x[0], y[1], z[1]) + tx * n(x[1], y[1], z[1]);
    let c0 = (1.0 - ty) * c00 + ty * c10;
    let c1 = (1.0 - ty) * c01 + ty * c11;
    (1.0 - tz) * c0 + tz * c1
}

/// (W, ∂(W − t)²/∂R) at voxel (i, j, k) of `moving` through the warp `lattice`, against the
/// target value `t`; all zero outside (warped_sample in shaders/warp_sample.wgsl).
#[inline]
pub fn warped_sample(
    params: &RbfGradParams,
    lattice: &[f32],
    taps: &LatticeTaps,
    moving: &[f32],
    [i, j, k]: [u32; 3],
    t: f32,
) -> [f32; 4] {
    let d = [params.dims[0], params.dims[1], params.dims[2]];
    let r = warp_at(params, lattice, taps, [i, j, k]).to_array();
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
    let taps = LatticeTaps::new(params);
    warped
        .par_chunks_mut((nx * ny) as usize)
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..ny {
                for i in 0..nx {
                    slice[(i + nx * j) as usize] =
                        warped_sample(params, lattice, &taps, moving, [i, j, k as u32], 0.0)[0];
                }
            }
        });
}
