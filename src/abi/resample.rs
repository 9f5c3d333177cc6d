//! Resampling through a field, the per-cell SSD and the intensity gain.

use super::*;

/// How a resample reads the source between voxel centres.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// Trilinear (intensities).
    #[default]
    Linear,
    /// Nearest voxel centre (label maps: no invented in-between codes).
    Nearest,
}

/// Keep in sync with `ResampleParams` in shaders/resample.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct ResampleParams {
    /// Target nx, ny, nz, unused.
    pub target_dims: [u32; 4],
    /// Source nx, ny, nz, unused.
    pub source_dims: [u32; 4],
    /// Rows of (source world→index) · (target index→world): target voxel → source index.
    pub index_to_source: [[f32; 4]; 3],
    /// Rows of the linear part of source world→index: a displacement in mm → index delta.
    pub mm_to_source: [[f32; 4]; 3],
    /// Value for points outside the source.
    pub background: f32,
    /// 0: trilinear; 1: nearest neighbour (label maps).
    pub nearest: u32,
    /// Padding to a multiple of 16 bytes.
    pub pad: [u32; 2],
}

impl ResampleParams {
    /// Parameters to resample a volume on `source` onto `target` through a displacement field.
    pub fn new(
        source: &Grid,
        target: &Grid,
        background: f32,
        interpolation: Interpolation,
    ) -> Self {
        let to_source = source.world_to_voxel_affine();
        let combined = snap_to_integers(&(to_source * target.affine));
        let linear = snap_to_integers(&to_source);
        let row = |m: &Affine, r: usize, with_offset: bool| {
            [
                m[(r, 0)] as f32,
                m[(r, 1)] as f32,
                m[(r, 2)] as f32,
                if with_offset { m[(r, 3)] as f32 } else { 0.0 },
            ]
        };
        ResampleParams {
            target_dims: [
                target.dims[0] as u32,
                target.dims[1] as u32,
                target.dims[2] as u32,
                0,
            ],
            source_dims: [
                source.dims[0] as u32,
                source.dims[1] as u32,
                source.dims[2] as u32,
                0,
            ],
            index_to_source: std::array::from_fn(|r| row(&combined, r, true)),
            mm_to_source: std::array::from_fn(|r| row(&linear, r, false)),
            background,
            nearest: (interpolation == Interpolation::Nearest) as u32,
            pad: [0; 2],
        }
    }

    /// Voxels of the target grid.
    pub fn voxels(&self) -> usize {
        count(&self.target_dims)
    }
}

/// Keep in sync with `SsdParams` in shaders/ssd_cells.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SsdParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Cells along x, y, z, unused.
    pub cells: [u32; 4],
}

impl SsdParams {
    /// Parameters for an (nx, ny, nz) volume split into `cells`.
    pub fn new(dims: [usize; 3], cells: [usize; 3]) -> Self {
        SsdParams {
            dims: [dims[0] as u32, dims[1] as u32, dims[2] as u32, 0],
            cells: [cells[0] as u32, cells[1] as u32, cells[2] as u32, 0],
        }
    }

    /// Partial sums the kernel writes: nz · nx · cy.
    pub fn partials(&self) -> usize {
        (self.dims[2] * self.dims[0] * self.cells[1]) as usize
    }
}

/// Coverage at or above which a voxel of the moving image holds data from the source scan
/// (`is_covered` in shaders/common.wgsl): 0 or 1 at the finest level, fractional after the
/// pyramid's smoothing, which erodes it.
pub const COVERED_AT: f32 = 0.999;

/// Keep in sync with `GainParams` in shaders/gain.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct GainParams {
    /// nx, ny, nz of the grid written, its voxels.
    pub dims: [u32; 4],
    /// nx, ny, nz of the smoothed grid, unused.
    pub coarse_dims: [u32; 4],
    /// Voxel index of the grid written → continuous index of the smoothed grid.
    pub to_coarse: [[f32; 4]; 3],
    /// Energy floor, most gain, unused ×2.
    pub limits: [f32; 4],
}

impl GainParams {
    /// For kernels writing `grid`, the gain smoothed on `coarse`, ratios kept within a factor
    /// `most` of 1 and set to 1 where the smoothed energy is at or below `floor`.
    pub fn new(grid: &Grid, coarse: &Grid, floor: f32, most: f32) -> Self {
        GainParams {
            dims: dims4(grid, grid.len() as u32),
            coarse_dims: dims4(coarse, 0),
            to_coarse: rows(&(coarse.world_to_voxel_affine() * grid.affine)),
            limits: [floor, most, 0.0, 0.0],
        }
    }

    /// Voxels of the grid written.
    pub fn voxels(&self) -> usize {
        self.dims[3] as usize
    }
}
