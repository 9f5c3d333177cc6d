//! CPU twin of shaders/sampling/resample.wgsl: one target slice per rayon task, a row of
//! voxels at a time.

use crate::abi::ResampleParams;
use crate::cpu::row_cells::RowCells;
use crate::sample::{array_from, nearest};
use rayon::prelude::*;

/// Fills `warped` (one value per target voxel) from `source` and the packed field (3 floats
/// per target voxel).
pub fn resample(params: &ResampleParams, source: &[f32], field: &[f32], warped: &mut [f32]) {
    // Rows of `warped` and `field` are paired below; a short field must not leave rows unwritten.
    assert_eq!(
        field.len(),
        3 * warped.len(),
        "resample: field and output differ in length"
    );
    let [nx, ny, _, _] = params.target_dims.map(|n| n as usize);
    warped
        .par_chunks_mut(nx * ny)
        .zip(field.par_chunks(3 * nx * ny))
        .enumerate()
        .for_each_init(RowSamples::default, |samples, (k, (out, field))| {
            let rows = out.chunks_exact_mut(nx).zip(field.chunks_exact(3 * nx));
            for (j, (out, field)) in rows.enumerate() {
                resample_row(samples, params, source, [j as u32, k as u32], (field, out));
            }
        });
}

/// One row's cells in the source, whether each point lies inside it, and the source at the
/// cells' corners, each per voxel of the row.
#[derive(Default)]
struct RowSamples {
    cells: RowCells,
    inside: Vec<bool>,
    corners: [Vec<f32>; 8],
}

/// Row (j, k) of the shader: the points, then (nearest) their voxels, or (linear) their cells,
/// the corners' values and the blends, in passes over the row's voxels so that every pass but
/// the gather vectorises. Each voxel's operations are the shader's, in its order, so the values
/// are the same bits (a point outside is looked up in its clamped cell too, and its value then
/// dropped for the background). Also compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn resample_row(
    samples: &mut RowSamples,
    params: &ResampleParams,
    source: &[f32],
    [j, k]: [u32; 2],
    (field, out): (&[f32], &mut [f32]),
) {
    let nx = out.len();
    let d = [
        params.source_dims[0],
        params.source_dims[1],
        params.source_dims[2],
    ];
    let cells = &mut samples.cells;
    cells.resize(nx);
    cells.place([j, k], (params.index_to_source, params.mm_to_source), field);
    let point = |i: usize| array_from(|a| cells.position[a][i]);
    if params.nearest == 1 {
        for (i, out) in out.iter_mut().enumerate() {
            *out = nearest(source, point(i), d, params.background);
        }
        return;
    }
    cells.inside(nx, d, &mut samples.inside);
    cells.locate(nx, d);
    cells.gather(nx, source, &mut samples.corners);
    cells.blend(nx, &samples.corners, out);
    for (out, &inside) in out.iter_mut().zip(&samples.inside) {
        if !inside {
            *out = params.background;
        }
    }
}
