//! CPU twin of shaders/common.wgsl: same names, same order of operations.

/// Flat index of voxel (i, j, k) in an x-fastest volume of size dims.
pub fn voxel_index(i: u32, j: u32, k: u32, dims: [u32; 3]) -> u32 {
    i + dims[0] * (j + dims[1] * k)
}

/// One row of a 3x4 affine applied to a point, summed left to right.
pub fn affine_row(row: [f32; 4], p: [f32; 3]) -> f32 {
    row[0] * p[0] + row[1] * p[1] + row[2] * p[2] + row[3]
}

/// One row of a 3x3 linear map applied to a vector.
pub fn linear_row(row: [f32; 4], v: [f32; 3]) -> f32 {
    row[0] * v[0] + row[1] * v[1] + row[2] * v[2]
}

/// First index of cell c when n voxels are split into `cells` cells.
// Written as in WGSL, which has no div_ceil.
#[allow(clippy::manual_div_ceil)]
pub fn cell_start(c: u32, n: u32, cells: u32) -> u32 {
    (c * n + cells - 1) / cells
}
