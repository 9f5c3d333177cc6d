//! Local correlation: box moments and the LNCC cost and gradient terms.

use super::*;

/// Local moments per voxel: Σa, Σb, Σa², Σb², Σab over a box window (shaders/correlation/local_moments.wgsl).
pub const LOCAL_MOMENTS: usize = 5;

/// Keep in sync with `LocalMomentsParams` in shaders/correlation/local_moments.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LocalMomentsParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Axis of this pass (0 x, 1 y, 2 z).
    pub axis: u32,
    /// 1 on the first pass (it reads the two images), 0 on the others (they read the stack).
    pub first: u32,
    /// The window's radius (voxels).
    pub radius: u32,
    /// Padding to 16 bytes.
    pub pad: u32,
}

impl LocalMomentsParams {
    /// The x, y and z passes summing two images' [`LOCAL_MOMENTS`] on `grid` over a box of
    /// (2 `radius` + 1)³ voxels (cut at the grid's faces).
    pub fn passes(grid: &Grid, radius: usize) -> [LocalMomentsParams; 3] {
        std::array::from_fn(|axis| LocalMomentsParams {
            dims: dims4(grid, 0),
            axis: axis as u32,
            first: (axis == 0) as u32,
            radius: radius as u32,
            pad: 0,
        })
    }

    /// The x, y and z passes summing a stack of [`LOCAL_MOMENTS`] values per voxel on `grid`
    /// (as lncc_terms writes) over the same boxes.
    pub fn stack_passes(grid: &Grid, radius: usize) -> [LocalMomentsParams; 3] {
        std::array::from_fn(|axis| LocalMomentsParams {
            dims: dims4(grid, 0),
            axis: axis as u32,
            first: 0,
            radius: radius as u32,
            pad: 0,
        })
    }

    /// Values written: [`LOCAL_MOMENTS`] per voxel.
    pub fn values(&self) -> usize {
        LOCAL_MOMENTS * count(&self.dims)
    }
}

/// Keep in sync with `LnccTermsParams` in shaders/correlation/lncc_terms.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LnccTermsParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// The cost's scale K.
    pub scale: f32,
    /// The window's radius (voxels).
    pub radius: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 2],
}

impl LnccTermsParams {
    /// For [`LOCAL_MOMENTS`] summed on `grid` over windows of `radius` voxels; the cost is
    /// `scale` Σ c (1 − ρ²).
    pub fn new(grid: &Grid, radius: usize, scale: f32) -> Self {
        LnccTermsParams {
            dims: dims4(grid, 0),
            scale,
            radius: radius as u32,
            pad: [0; 2],
        }
    }

    /// Values written to the terms: [`LOCAL_MOMENTS`] per voxel.
    pub fn values(&self) -> usize {
        LOCAL_MOMENTS * count(&self.dims)
    }

    /// Rows of x (ny · nz): one cost sum per row.
    pub fn rows(&self) -> usize {
        (self.dims[1] * self.dims[2]) as usize
    }
}

/// Keep in sync with `LnccParams` in shaders/correlation/lncc.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LnccParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Voxels, voxels per chunk ([`STATS_CHUNK`]), chunks, unused.
    pub chunks: [u32; 4],
    /// The window's radius (voxels).
    pub radius: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}

impl LnccParams {
    /// For [`LOCAL_MOMENTS`] summed on `grid` over windows of `radius` voxels.
    pub fn new(grid: &Grid, radius: usize) -> Self {
        LnccParams {
            dims: dims4(grid, 0),
            chunks: chunking(grid.len(), STATS_CHUNK, 0),
            radius: radius as u32,
            pad: [0; 3],
        }
    }

    /// Chunks the kernel writes 2 values for.
    pub fn chunks(&self) -> usize {
        self.chunks[2] as usize
    }
}
