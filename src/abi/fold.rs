//! Folds: thresholds, the Jacobian determinant and its statistics, the dilation of a mask.

use super::*;

/// Voxels per chunk of the fold statistics and the moments.
pub const STATS_CHUNK: usize = 1024;
/// Floats of fold statistics per chunk (shaders/fold/fold_stats.wgsl): minimum, folded, at most the
/// threshold, of those not held, folded bone contacts.
pub const FOLD_STATS_WIDTH: usize = 5;

/// Keep in sync with `ThresholdParams` in shaders/fold/threshold.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct ThresholdParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Voxels, voxels per chunk ([`STATS_CHUNK`]), chunks, unused.
    pub chunks: [u32; 4],
    /// The threshold (det J for the folds, mm for a distance).
    pub threshold: f32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}

impl ThresholdParams {
    /// For a value per voxel of `grid` compared with `threshold`.
    pub fn new(grid: &Grid, threshold: f32) -> Self {
        ThresholdParams {
            dims: dims4(grid, 0),
            chunks: chunking(grid.len(), STATS_CHUNK, 0),
            threshold,
            pad: [0; 3],
        }
    }

    /// Voxels of the grid.
    pub fn voxels(&self) -> usize {
        self.chunks[0] as usize
    }

    /// Chunks fold_stats writes [`FOLD_STATS_WIDTH`] floats for.
    pub fn chunks(&self) -> usize {
        self.chunks[2] as usize
    }
}

/// Keep in sync with `JacobianParams` in shaders/fold/jacobian.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct JacobianParams {
    /// nx, ny, nz of the field's grid, unused.
    pub dims: [u32; 4],
    /// Rows of the inverse of the grid's linear part: d(index)/d(world mm).
    pub mm_to_index: [[f32; 4]; 3],
}

impl JacobianParams {
    /// Voxels of the field's grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }

    /// Parameters for the Jacobian of a field on `grid`.
    pub fn new(grid: &Grid) -> Self {
        JacobianParams {
            dims: dims4(grid, 0),
            mm_to_index: mm_to_index_rows(grid),
        }
    }
}

/// Keep in sync with `DilateParams` in shaders/fold/dilate.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct DilateParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Axis (0 x, 1 y, 2 z).
    pub axis: u32,
    /// 1 to clear the held voxels.
    pub clear_held: u32,
    /// The margin (voxels).
    pub margin: u32,
    /// Padding to 16 bytes.
    pub pad: u32,
}

impl DilateParams {
    /// The passes dilating a mask on `grid` by `margin` voxels along x, y and z, the last
    /// clearing the held voxels.
    pub fn passes(grid: &Grid, margin: usize) -> [DilateParams; 3] {
        std::array::from_fn(|axis| DilateParams {
            dims: dims4(grid, 0),
            axis: axis as u32,
            clear_held: (axis == 2) as u32,
            margin: margin as u32,
            pad: 0,
        })
    }

    /// Voxels of the grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }
}
