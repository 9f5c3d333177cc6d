//! CPU twin of shaders/common.wgsl: same names, same order of operations.

pub use crate::sample::{affine_row, linear_row, source_index, voxel_index};

/// Coverage at or above which a voxel holds data from the source scan.
#[inline]
pub fn is_covered(coverage: f32) -> bool {
    coverage >= crate::abi::COVERED_AT
}

/// First index of cell c when n voxels are split into `cells` cells.
// Written as in WGSL, which has no div_ceil.
#[allow(clippy::manual_div_ceil)]
#[inline]
pub fn cell_start(c: u32, n: u32, cells: u32) -> u32 {
    (c * n + cells - 1) / cells
}

/// Central difference between a voxel's neighbours `lo` and `hi` along an axis, at coordinate
/// c of n: one-sided at the ends, 0 along an axis one voxel long (jacobian.wgsl's `difference`,
/// dense_force.wgsl's `slope`).
#[inline(always)]
pub fn difference(lo: f32, hi: f32, c: u32, n: u32) -> f32 {
    if n == 1 {
        return 0.0;
    }
    if c == 0 || c == n - 1 {
        return hi - lo;
    }
    (hi - lo) * 0.5
}

/// Determinant of the 3×3 matrix with rows r0, r1, r2 (cofactors of the first row).
#[inline]
pub fn det3(r0: glam::Vec3, r1: glam::Vec3, r2: glam::Vec3) -> f32 {
    r0.x * (r1.y * r2.z - r1.z * r2.y) - r0.y * (r1.x * r2.z - r1.z * r2.x)
        + r0.z * (r1.x * r2.y - r1.y * r2.x)
}

/// Solves A s = e for A with rows r0, r1, r2 by Cramer's rule; `det` = det3(r0, r1, r2) ≠ 0.
#[inline]
pub fn solve3(
    r0: glam::Vec3,
    r1: glam::Vec3,
    r2: glam::Vec3,
    det: f32,
    e: glam::Vec3,
) -> glam::Vec3 {
    use glam::Vec3;
    let sx = det3(
        Vec3::new(e.x, r0.y, r0.z),
        Vec3::new(e.y, r1.y, r1.z),
        Vec3::new(e.z, r2.y, r2.z),
    );
    let sy = det3(
        Vec3::new(r0.x, e.x, r0.z),
        Vec3::new(r1.x, e.y, r1.z),
        Vec3::new(r2.x, e.z, r2.z),
    );
    let sz = det3(
        Vec3::new(r0.x, r0.y, e.x),
        Vec3::new(r1.x, r1.y, e.y),
        Vec3::new(r2.x, r2.y, e.z),
    );
    Vec3::new(sx, sy, sz) / det
}

/// The dims of a params struct's [nx, ny, nz, _] as u32s.
#[inline]
pub fn dims3(dims: [u32; 4]) -> [u32; 3] {
    [dims[0], dims[1], dims[2]]
}
