//! CPU twin of shaders/field/compose.wgsl.

use crate::abi::ComposeParams;
use crate::cpu::row_cells::RowCells;
use rayon::prelude::*;

/// Fills `out` (3 floats per voxel) with u = R + u0 ∘ (id + R), `warp` holding R and
/// `initial` u0 (3 floats per voxel each, u0 on its own grid).
pub fn compose(params: &ComposeParams, warp: &[f32], initial: &[f32], out: &mut [f32]) {
    // Rows of `out` and `warp` are paired below; a short warp must not leave rows unwritten.
    assert_eq!(
        warp.len(),
        out.len(),
        "compose: warp and output differ in length"
    );
    let [nx, ny, _, _] = params.dims;
    let row = 3 * nx as usize;
    out.par_chunks_mut(row * ny as usize)
        .zip(warp.par_chunks(row * ny as usize))
        .enumerate()
        .for_each_init(RowSamples::default, |cells, (k, (out, warp))| {
            let rows = out.chunks_exact_mut(row).zip(warp.chunks_exact(row));
            for (j, (out, warp)) in rows.enumerate() {
                compose_row(cells, params, initial, [j as u32, k as u32], (warp, out));
            }
        });
}

/// One row's cells of u0 and u0's values at their corners, each per voxel of the row.
#[derive(Default)]
struct RowSamples {
    cells: RowCells,
    corners: [[Vec<f32>; 8]; 3],
    blended: [Vec<f32>; 3],
}

impl RowSamples {
    /// Every lane `nx` long.
    fn resize(&mut self, nx: usize) {
        self.cells.resize(nx);
        let floats = self.corners.iter_mut().flatten().chain(&mut self.blended);
        for lane in floats {
            lane.resize(nx, 0.0);
        }
    }
}

/// Row (j, k) of the shader's u = R + u0 ∘ (id + R), in passes over the row's voxels (the
/// clamped points, their cells per axis, the corners' indices, u0 at the corners, the blends)
/// so that every pass but the gather vectorises. Each voxel's operations are the shader's, in
/// its order, so the values are the same bits; the shader samples each component through
/// sampled_value, and the three share one cell, found once here. Also compiled for AVX2
/// (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn compose_row(
    samples: &mut RowSamples,
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
    samples.resize(nx);
    let cells = &mut samples.cells;
    cells.place(
        [j, k],
        (params.index_to_initial, params.mm_to_initial),
        warp,
    );
    // u0's edge values continue beyond its grid.
    for (position, &n) in cells.position.iter_mut().zip(&e) {
        for q in &mut position[..nx] {
            *q = q.clamp(0.0, n as f32 - 1.0);
        }
    }
    cells.locate(nx, e);
    // u0's three components lie together: each corner's are read at once (RowCells::gather
    // reads one value per corner).
    for (c, at) in cells.at.iter().enumerate() {
        let [x, y, z] = samples.corners.each_mut().map(|lanes| &mut lanes[c][..nx]);
        for (i, &at) in at[..nx].iter().enumerate() {
            let v = &initial[3 * at as usize..][..3];
            (x[i], y[i], z[i]) = (v[0], v[1], v[2]);
        }
    }
    for (corners, blended) in samples.corners.iter().zip(&mut samples.blended) {
        cells.blend(nx, corners, blended);
    }
    for (i, (out, warp)) in out
        .chunks_exact_mut(3)
        .zip(warp.chunks_exact(3))
        .enumerate()
    {
        for m in 0..3 {
            out[m] = warp[m] + samples.blended[m][i];
        }
    }
}
