//! CPU twin of shaders/sampling/coverage.wgsl: one target slice per rayon task, a row of voxels
//! at a time.

use crate::abi::ResampleParams;
use crate::cpu::row_cells::RowCells;
use rayon::prelude::*;

/// Fills `covered` (1 float per target voxel) with 1 where the voxel's source point lies inside
/// the source and the voxel in `mask` (> 0), else 0.
pub fn coverage(params: &ResampleParams, field: &[f32], mask: &[f32], covered: &mut [f32]) {
    // Rows of `covered`, `field` and `mask` are paired below; short inputs must not leave rows
    // unwritten.
    assert_eq!(
        field.len(),
        3 * covered.len(),
        "coverage: field and output differ in length"
    );
    assert_eq!(
        mask.len(),
        covered.len(),
        "coverage: mask and output differ in length"
    );
    let [nx, ny, _, _] = params.target_dims.map(|n| n as usize);
    covered
        .par_chunks_mut(nx * ny)
        .zip(field.par_chunks(3 * nx * ny).zip(mask.par_chunks(nx * ny)))
        .enumerate()
        .for_each_init(RowPoints::default, |points, (k, (out, (field, mask)))| {
            let rows = out
                .chunks_exact_mut(nx)
                .zip(field.chunks_exact(3 * nx).zip(mask.chunks_exact(nx)));
            for (j, (out, (field, mask))) in rows.enumerate() {
                covered_row(points, params, [j as u32, k as u32], (field, mask), out);
            }
        });
}

/// One row's source points and whether each lies inside the source.
#[derive(Default)]
struct RowPoints {
    cells: RowCells,
    inside: Vec<bool>,
}

/// Row (j, k) of the shader, in passes over the row's voxels (the points, whether each is
/// inside, the mask) so that they vectorise; each point is the shader's source_index, in its
/// order. Also compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn covered_row(
    points: &mut RowPoints,
    params: &ResampleParams,
    [j, k]: [u32; 2],
    (field, mask): (&[f32], &[f32]),
    out: &mut [f32],
) {
    let nx = out.len();
    let cells = &mut points.cells;
    cells.resize(nx);
    cells.place([j, k], (params.index_to_source, params.mm_to_source), field);
    let dims = [
        params.source_dims[0],
        params.source_dims[1],
        params.source_dims[2],
    ];
    cells.inside(nx, dims, &mut points.inside);
    for ((out, &inside), &mask) in out.iter_mut().zip(&points.inside).zip(mask) {
        *out = if inside && mask > 0.0 { 1.0 } else { 0.0 };
    }
}
