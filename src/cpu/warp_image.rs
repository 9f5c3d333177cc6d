//! CPU twin of shaders/warp_image.wgsl, with the lattice warp and the warped sample it shares
//! with the cost's twins (shaders/lattice_warp.wgsl, shaders/warp_sample.wgsl).

use super::common::{linear_row, voxel_index};
use crate::abi::RbfGradParams;
use crate::sample::{inside_source, trilinear_with_gradient};
use glam::Vec3;
use rayon::prelude::*;

/// Where each voxel coordinate falls between lattice nodes, per axis: the shader's (i0, i1, t)
/// for coordinate c at [a][c]. Computed once per call: per voxel, its three integer divisions
/// cost as much as the rest of the interpolation.
pub struct LatticeTaps {
    axes: [Vec<([u32; 2], f32)>; 3],
}

impl LatticeTaps {
    /// The taps of every voxel coordinate of `params`' grid.
    pub fn new(params: &RbfGradParams) -> Self {
        LatticeTaps {
            axes: std::array::from_fn(|a| {
                let s = params.lattice_step[a];
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

    /// The lattice columns voxel row (j, k) (along x) interpolates between, blended along y
    /// and z once for the whole row.
    #[inline]
    pub fn row(&self, params: &RbfGradParams, lattice: &[f32], j: u32, k: u32) -> RowTaps {
        let ([y0, y1], ty) = self.axes[1][j as usize];
        let ([z0, z1], tz) = self.axes[2][k as usize];
        let l = [
            params.lattice_dims[0],
            params.lattice_dims[1],
            params.lattice_dims[2],
        ];
        let node = |x, y, z| {
            let n = 3 * voxel_index(x, y, z, l) as usize;
            Vec3::from_slice(&lattice[n..n + 3])
        };
        // shaders/lattice_warp.wgsl's column(), for every x node.
        let columns = (0..l[0])
            .map(|x| {
                let c0 = (1.0 - ty) * node(x, y0, z0) + ty * node(x, y1, z0);
                let c1 = (1.0 - ty) * node(x, y0, z1) + ty * node(x, y1, z1);
                (1.0 - tz) * c0 + tz * c1
            })
            .collect();
        RowTaps { columns }
    }
}

/// The lattice of one voxel row blended along y and z (one column per x node): the node
/// lookups and the y and z interpolation of a row, done once.
pub struct RowTaps {
    columns: Vec<Vec3>,
}

impl RowTaps {
    /// Trilinear interpolation of the lattice at voxel i of the row, in the shader's order.
    #[inline]
    pub fn warp_at(&self, taps: &LatticeTaps, i: u32) -> Vec3 {
        let ([x0, x1], tx) = taps.axes[0][i as usize];
        (1.0 - tx) * self.columns[x0 as usize] + tx * self.columns[x1 as usize]
    }
}

/// Trilinear interpolation of the lattice at voxel (i, j, k).
pub fn warp_at(params: &RbfGradParams, lattice: &[f32], taps: &LatticeTaps, c: [u32; 3]) -> Vec3 {
    taps.row(params, lattice, c[1], c[2]).warp_at(taps, c[0])
}

/// Where voxel (i, j, k) samples I0 through the warp of `row`, in I0's index space: x + R(x)
/// (warped_position in shaders/warp_sample.wgsl).
#[inline]
fn warped_position(
    params: &RbfGradParams,
    row: &RowTaps,
    taps: &LatticeTaps,
    [i, j, k]: [u32; 3],
) -> [f32; 3] {
    let r = row.warp_at(taps, i).to_array();
    [
        i as f32 + linear_row(params.mm_to_index[0], r),
        j as f32 + linear_row(params.mm_to_index[1], r),
        k as f32 + linear_row(params.mm_to_index[2], r),
    ]
}

/// (W, ∂(W − t)²/∂R) at voxel (i, j, k) of `moving` through the warp of `row`, against the
/// target value `t`; all zero outside (warped_sample in shaders/warp_sample.wgsl).
#[inline]
pub fn warped_sample(
    params: &RbfGradParams,
    row: &RowTaps,
    taps: &LatticeTaps,
    moving: &[f32],
    ijk: [u32; 3],
    t: f32,
) -> [f32; 4] {
    let d = [params.dims[0], params.dims[1], params.dims[2]];
    let q = warped_position(params, row, taps, ijk);
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

/// (W, ∇I0(x + R(x))) at voxel (i, j, k) of `moving` through the warp of `row`, the gradient in
/// world mm; all zero outside (warped_value_gradient in shaders/warp_sample.wgsl).
#[inline]
pub fn warped_value_gradient(
    params: &RbfGradParams,
    row: &RowTaps,
    taps: &LatticeTaps,
    moving: &[f32],
    ijk: [u32; 3],
) -> [f32; 4] {
    let d = [params.dims[0], params.dims[1], params.dims[2]];
    let q = warped_position(params, row, taps, ijk);
    if !inside_source(q, d) {
        return [0.0; 4];
    }
    let vg = trilinear_with_gradient(moving, q, d);
    let g = [vg[1], vg[2], vg[3]];
    [
        vg[0],
        linear_row(params.gradient_to_world[0], g),
        linear_row(params.gradient_to_world[1], g),
        linear_row(params.gradient_to_world[2], g),
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
                let row = taps.row(params, lattice, j, k as u32);
                for i in 0..nx {
                    slice[(i + nx * j) as usize] =
                        warped_sample(params, &row, &taps, moving, [i, j, k as u32], 0.0)[0];
                }
            }
        });
}
