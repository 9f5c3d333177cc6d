// common.wgsl: helpers shared by every kernel; prepended to each kernel's source.
// Mirrored on the CPU in src/cpu/common.rs: keep the arithmetic (order of operations) identical,
// so the twins agree bit for bit where the driver does not fuse multiply-adds.

// Flat index of voxel (i, j, k) in an x-fastest volume of size dims.
fn voxel_index(i: u32, j: u32, k: u32, dims: vec3<u32>) -> u32 {
    return i + dims.x * (j + dims.y * k);
}

// One row of a 3x4 affine applied to a point: row.xyz . p + row.w, summed left to right.
fn affine_row(row: vec4<f32>, p: vec3<f32>) -> f32 {
    return row.x * p.x + row.y * p.y + row.z * p.z + row.w;
}

// One row of a 3x3 linear map applied to a vector (row.w ignored).
fn linear_row(row: vec4<f32>, v: vec3<f32>) -> f32 {
    return row.x * v.x + row.y * v.y + row.z * v.z;
}

// Whether continuous voxel index q lies inside a volume of `dims`: every coordinate in
// [-0.5, n - 0.5] (ITK's rule: half a voxel beyond the outer centres).
fn inside_source(q: vec3<f32>, dims: vec3<u32>) -> bool {
    return all(q >= vec3<f32>(-0.5)) && all(q <= vec3<f32>(dims) - vec3<f32>(0.5));
}

// Coverage at or above which a voxel of the moving image holds data from the source scan
// (abi::COVERED_AT): coverage is 0 or 1 at the finest level and fractional after the
// pyramid's smoothing, which erodes it.
fn is_covered(coverage: f32) -> bool {
    return coverage >= 0.999;
}

// First index of cell c when n voxels are split into `cells` cells: voxel i belongs to cell
// floor(i * cells / n), so cell c starts at ceil(c * n / cells).
fn cell_start(c: u32, n: u32, cells: u32) -> u32 {
    return (c * n + cells - 1u) / cells;
}

// Determinant of the 3x3 matrix with rows r0, r1, r2, by cofactors of the first row (written
// out so the CPU twin follows the same order).
fn det3(r0: vec3<f32>, r1: vec3<f32>, r2: vec3<f32>) -> f32 {
    return r0.x * (r1.y * r2.z - r1.z * r2.y)
        - r0.y * (r1.x * r2.z - r1.z * r2.x)
        + r0.z * (r1.x * r2.y - r1.y * r2.x);
}

// Solves A s = e for A with rows r0, r1, r2 by Cramer's rule; `det` is det3(r0, r1, r2) != 0.
fn solve3(r0: vec3<f32>, r1: vec3<f32>, r2: vec3<f32>, det: f32, e: vec3<f32>) -> vec3<f32> {
    let sx = det3(vec3<f32>(e.x, r0.y, r0.z), vec3<f32>(e.y, r1.y, r1.z), vec3<f32>(e.z, r2.y, r2.z));
    let sy = det3(vec3<f32>(r0.x, e.x, r0.z), vec3<f32>(r1.x, e.y, r1.z), vec3<f32>(r2.x, e.z, r2.z));
    let sz = det3(vec3<f32>(r0.x, r0.y, e.x), vec3<f32>(r1.x, r1.y, e.y), vec3<f32>(r2.x, r2.y, e.z));
    return vec3<f32>(sx, sy, sz) / det;
}
