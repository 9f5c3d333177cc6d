//! CPU twin of shaders/field/compose.wgsl.

use crate::abi::ComposeParams;
use crate::cpu::common::linear_row;
use crate::sample::{affine_row, array_from, axis_corners, blend_corners, corner_index};
use rayon::prelude::*;

/// Fills `out` (3 floats per voxel) with u = R + u0 ∘ (id + R), `warp` holding R and
/// `initial` u0 (3 floats per voxel each, u0 on its own grid).
pub fn compose(params: &ComposeParams, warp: &[f32], initial: &[f32], out: &mut [f32]) {
    let [nx, ny, _, _] = params.dims;
    let row = 3 * nx as usize;
    out.par_chunks_mut(row * ny as usize)
        .zip(warp.par_chunks(row * ny as usize))
        .enumerate()
        .for_each_init(RowCells::default, |cells, (k, (out, warp))| {
            let rows = out.chunks_exact_mut(row).zip(warp.chunks_exact(row));
            for (j, (out, warp)) in rows.enumerate() {
                compose_row(cells, params, initial, [j as u32, k as u32], (warp, out));
            }
        });
}

/// One row's points, the cells of u0 they fall in and u0's values at the cells' corners, each
/// per voxel of the row.
#[derive(Default)]
struct RowCells {
    position: [Vec<f32>; 3],
    fraction: [Vec<f32>; 3],
    ends: [[Vec<u32>; 2]; 3],
    at: [Vec<u32>; 8],
    corners: [[Vec<f32>; 8]; 3],
    blended: [Vec<f32>; 3],
}

impl RowCells {
    /// Every lane `nx` long.
    fn resize(&mut self, nx: usize) {
        let floats = self.position.iter_mut().chain(&mut self.fraction);
        let floats = floats.chain(&mut self.blended);
        for lane in floats.chain(self.corners.iter_mut().flatten()) {
            lane.resize(nx, 0.0);
        }
        for lane in self.ends.iter_mut().flatten().chain(&mut self.at) {
            lane.resize(nx, 0);
        }
    }
}

/// Row (j, k) of the shader's u = R + u0 ∘ (id + R), in passes over the row's voxels (the
/// clamped points, their cells per axis, the corners' indices, u0 at the corners, the blends)
/// so that every pass but the gather vectorises. Each voxel's operations are the shader's, in
/// its order, so the values are the same bits. Also compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn compose_row(
    cells: &mut RowCells,
    params: &ComposeParams,
    initial: &[f32],
    [j, k]: [u32; 2],
    (warp, out): (&[f32], &mut [f32]),
) {
    let nx = params.dims[0] as usize;
    let e = [
        params.initial_dims[0],
        params.initial_dims[1],
        params.initial_dims[2],
    ];
    cells.resize(nx);
    for (a, &n) in e.iter().enumerate() {
        let (to_initial, mm_to_initial) = (params.index_to_initial[a], params.mm_to_initial[a]);
        let top = n as f32 - 1.0;
        for (i, q) in cells.position[a][..nx].iter_mut().enumerate() {
            let r = [warp[3 * i], warp[3 * i + 1], warp[3 * i + 2]];
            let x = [i as f32, j as f32, k as f32];
            *q = (affine_row(to_initial, x) + linear_row(mm_to_initial, r)).clamp(0.0, top);
        }
        let ([lower, upper], fraction) = (&mut cells.ends[a], &mut cells.fraction[a][..nx]);
        let (lower, upper) = (&mut lower[..nx], &mut upper[..nx]);
        for (i, &q) in cells.position[a][..nx].iter().enumerate() {
            ([lower[i], upper[i]], fraction[i]) = axis_corners(q, n);
        }
    }
    let ends = cells
        .ends
        .each_ref()
        .map(|[lower, upper]| [&lower[..nx], &upper[..nx]]);
    let mut at = cells.at.each_mut().map(|lane| &mut lane[..nx]);
    for i in 0..nx {
        let ends: [[u32; 2]; 3] = array_from(|a| [ends[a][0][i], ends[a][1][i]]);
        for (c, lane) in at.iter_mut().enumerate() {
            lane[i] = corner_index(c, ends, e);
        }
    }
    for (c, at) in cells.at.iter().enumerate() {
        let [x, y, z] = cells.corners.each_mut().map(|lanes| &mut lanes[c][..nx]);
        for (i, &at) in at[..nx].iter().enumerate() {
            let v = &initial[3 * at as usize..][..3];
            (x[i], y[i], z[i]) = (v[0], v[1], v[2]);
        }
    }
    let fraction: [&[f32]; 3] = std::array::from_fn(|a| &cells.fraction[a][..nx]);
    for (m, corners) in cells.corners.iter().enumerate() {
        let corners: [&[f32]; 8] = std::array::from_fn(|c| &corners[c][..nx]);
        let blended = &mut cells.blended[m][..nx];
        for (i, value) in blended.iter_mut().enumerate() {
            let t = array_from(|a| fraction[a][i]);
            *value = blend_corners(array_from(|c| corners[c][i]), t)[0];
        }
    }
    for (i, (out, warp)) in out
        .chunks_exact_mut(3)
        .zip(warp.chunks_exact(3))
        .enumerate()
    {
        for m in 0..3 {
            out[m] = warp[m] + cells.blended[m][i];
        }
    }
}
