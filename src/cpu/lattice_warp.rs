//! CPU twin of shaders/lattice_warp.wgsl and shaders/warp_sample.wgsl: the lattice warp and
//! the moving image sampled through it, shared by the twins of warp_image, warp_cost,
//! warp_field and lncc_gradient.

use super::common::{linear_row, voxel_index};
use super::row_cells::RowCells;
use crate::abi::RbfGradParams;
use crate::sample::{array_from, blend_corners};
use glam::Vec3;

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
    pub fn row(&self, params: &RbfGradParams, lattice: &[f32], j: u32, k: u32) -> RowTaps {
        let mut row = RowTaps::default();
        self.fill_row(params, lattice, [j, k], &mut row);
        row
    }

    /// [`LatticeTaps::row`] into `row`, whose buffer is reused.
    #[inline(always)]
    fn fill_row(
        &self,
        params: &RbfGradParams,
        lattice: &[f32],
        [j, k]: [u32; 2],
        row: &mut RowTaps,
    ) {
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
        // shaders/lattice_warp.wgsl's column(), for every x node. A loop, not extend over a
        // map: the compiler left that closure uninlined, out of the caller's AVX2 build.
        row.columns.resize(l[0] as usize, Vec3::ZERO);
        for (x, column) in (0..).zip(&mut row.columns) {
            let c0 = (1.0 - ty) * node(x, y0, z0) + ty * node(x, y1, z0);
            let c1 = (1.0 - ty) * node(x, y0, z1) + ty * node(x, y1, z1);
            *column = (1.0 - tz) * c0 + tz * c1;
        }
    }
}

/// The lattice of one voxel row blended along y and z (one column per x node): the node
/// lookups and the y and z interpolation of a row, done once.
#[derive(Default)]
pub struct RowTaps {
    columns: Vec<Vec3>,
}

impl RowTaps {
    /// Trilinear interpolation of the lattice at voxel i of the row, in the shader's order.
    #[inline(always)]
    pub fn warp_at(&self, taps: &LatticeTaps, i: u32) -> Vec3 {
        let ([x0, x1], tx) = taps.axes[0][i as usize];
        (1.0 - tx) * self.columns[x0 as usize] + tx * self.columns[x1 as usize]
    }
}

/// Trilinear interpolation of the lattice at voxel (i, j, k).
pub fn warp_at(params: &RbfGradParams, lattice: &[f32], taps: &LatticeTaps, c: [u32; 3]) -> Vec3 {
    taps.row(params, lattice, c[1], c[2]).warp_at(taps, c[0])
}

/// Where voxel (i, j, k) samples I0 through the warp of `row`, in I0's index space: x + R(x),
/// x on I0's voxel stride · (i, j, k) (warped_position in shaders/warp_sample.wgsl).
#[inline(always)]
fn warped_position(
    params: &RbfGradParams,
    row: &RowTaps,
    taps: &LatticeTaps,
    [i, j, k]: [u32; 3],
) -> [f32; 3] {
    let r = row.warp_at(taps, i).to_array();
    let s = params.stride;
    [
        (i * s[0]) as f32 + linear_row(params.mm_to_index[0], r),
        (j * s[1]) as f32 + linear_row(params.mm_to_index[1], r),
        (k * s[2]) as f32 + linear_row(params.mm_to_index[2], r),
    ]
}

/// I0 and its gradient at x + R(x) for every voxel x of one row (warped_value_gradient in
/// shaders/warp_sample.wgsl, a row at a time). The row is done in passes over all its voxels
/// (the row's lattice columns, warped points, corners per axis, corners' indices, their
/// values, blends) so that every pass but the gather of values vectorises; each voxel's
/// operations are the shader's, in its order, so the values are the same bits.
#[derive(Default)]
pub struct RowSamples {
    /// Whether voxel i's warped point lies inside I0 (else its sample is all zero).
    pub inside: Vec<bool>,
    /// W, then ∂W/∂x, ∂W/∂y, ∂W/∂z (world mm), each per voxel of the row.
    pub sample: [Vec<f32>; 4],
    /// The row's lattice columns, then per voxel: the warped point and its cell, the
    /// corners' values.
    row: RowTaps,
    cells: RowCells,
    corners: [Vec<f32>; 8],
}

impl RowSamples {
    /// Samples row (j, k) of `moving` through the warp `lattice` (sample_row below).
    pub fn sample(
        &mut self,
        params: &RbfGradParams,
        taps: &LatticeTaps,
        lattice: &[f32],
        moving: &[f32],
        jk: [u32; 2],
    ) {
        sample_row(self, params, taps, lattice, moving, jk);
    }

    /// The points', cells' and samples' lanes `nx` long (`inside` and the corners' values
    /// are sized where RowCells fills them).
    fn resize(&mut self, nx: usize) {
        self.cells.resize(nx);
        for lane in &mut self.sample {
            lane.resize(nx, 0.0);
        }
    }
}

/// Samples row (j, k) of `moving` through the warp of `row`: the warped points, then
/// their corners' indices, the corners' values (the only loop that cannot vectorise) and
/// the blends. Also compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn sample_row(
    samples: &mut RowSamples,
    params: &RbfGradParams,
    taps: &LatticeTaps,
    lattice: &[f32],
    moving: &[f32],
    [j, k]: [u32; 2],
) {
    let nx = params.dims[0] as usize;
    let d = [
        params.moving_dims[0],
        params.moving_dims[1],
        params.moving_dims[2],
    ];
    samples.resize(nx);
    taps.fill_row(params, lattice, [j, k], &mut samples.row);
    for i in 0..nx {
        let q = warped_position(params, &samples.row, taps, [i as u32, j, k]);
        for (a, q) in q.into_iter().enumerate() {
            samples.cells.position[a][i] = q;
        }
    }
    samples.cells.inside(nx, d, &mut samples.inside);
    samples.cells.locate(nx, d);
    samples.cells.gather(nx, moving, &mut samples.corners);
    // Every lane cut to the row's length, so that the loop below has no bounds checks.
    let corners: [&[f32]; 8] = std::array::from_fn(|c| &samples.corners[c][..nx]);
    let fraction = samples.cells.fractions(nx);
    let inside = &samples.inside[..nx];
    let [s0, s1, s2, s3] = samples.sample.each_mut().map(|lane| &mut lane[..nx]);
    let to_world = params.gradient_to_world;
    for i in 0..nx {
        let vg = blend_corners(
            array_from(|c| corners[c][i]),
            array_from(|a| fraction[a][i]),
        );
        let g = [vg[1], vg[2], vg[3]];
        let keep = |value: f32| if inside[i] { value } else { 0.0 };
        s0[i] = keep(vg[0]);
        s1[i] = keep(linear_row(to_world[0], g));
        s2[i] = keep(linear_row(to_world[1], g));
        s3[i] = keep(linear_row(to_world[2], g));
    }
}
