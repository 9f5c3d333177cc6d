//! Fields: the fade off the bones, composition and inversion.

use super::*;

/// Keep in sync with `FadeParams` in shaders/field/fade_warp.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct FadeParams {
    /// nx, ny, nz of the warp's grid, unused.
    pub dims: [u32; 4],
    /// mm over which the warp rises from zero on a bone to its whole.
    pub margin: f32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}

impl FadeParams {
    /// For a warp on `grid` faded over `margin_mm` (> 0) from the nearest bone.
    pub fn new(grid: &Grid, margin_mm: f64) -> Self {
        FadeParams {
            dims: dims4(grid, 0),
            margin: margin_mm as f32,
            pad: [0; 3],
        }
    }

    /// Voxels of the grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `ComposeParams` in shaders/field/compose.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct ComposeParams {
    /// nx, ny, nz of the warp's (and the total field's) grid, unused.
    pub dims: [u32; 4],
    /// nx, ny, nz of the initial field's grid, unused.
    pub initial_dims: [u32; 4],
    /// Rows of (initial world→index) · (warp index→world): a warp voxel → initial index.
    pub index_to_initial: [[f32; 4]; 3],
    /// Rows of the linear part of initial world→index: a displacement in mm → index delta.
    pub mm_to_initial: [[f32; 4]; 3],
}

impl ComposeParams {
    /// Voxels of the warp's grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }

    /// For a warp on `grid` and an initial field on `initial` (the same grid inside one
    /// registration; the previous pose's grid when `posereg series` chains poses). The rows
    /// are resampling's, so one grid maps every voxel exactly onto itself.
    pub fn new(grid: &Grid, initial: &Grid) -> Self {
        let rows = ResampleParams::new(initial, grid, 0.0, Interpolation::Linear);
        ComposeParams {
            dims: rows.target_dims,
            initial_dims: rows.source_dims,
            index_to_initial: rows.index_to_source,
            mm_to_initial: rows.mm_to_source,
        }
    }
}

/// Keep in sync with `InvertParams` in shaders/field/invert_field.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct InvertParams {
    /// nx, ny, nz of the grid the inverse is sampled on (the source's), unused.
    pub out_dims: [u32; 4],
    /// nx, ny, nz of the field's grid (the target's), unused.
    pub field_dims: [u32; 4],
    /// Rows of (field world→index) · (out index→world): an output voxel → field index.
    pub index_to_field: [[f32; 4]; 3],
    /// Rows of the field grid's world→index linear part: mm → index delta.
    pub mm_to_index: [[f32; 4]; 3],
    /// Rows of the field grid's index→world linear part: index delta → mm.
    pub index_to_mm: [[f32; 4]; 3],
}

impl InvertParams {
    /// To invert a field on `field` onto the grid `out`.
    pub fn new(field: &Grid, out: &Grid) -> Self {
        let combined = snap_to_integers(&(field.world_to_voxel_affine() * out.affine));
        InvertParams {
            out_dims: dims4(out, 0),
            field_dims: dims4(field, 0),
            index_to_field: rows(&combined),
            mm_to_index: mm_to_index_rows(field),
            index_to_mm: linear_rows(&field.affine.fixed_view::<3, 3>(0, 0).into_owned()),
        }
    }

    /// Voxels of the output grid.
    pub fn voxels(&self) -> usize {
        count(&self.out_dims)
    }
}

/// Values per chunk of the round-trip statistics (shaders/field/round_trip_stats.wgsl): the sum
/// and largest residual, the voxels with a preimage, those beyond the far distance, those
/// without a preimage.
pub const ROUND_TRIP_WIDTH: usize = 5;

/// Keep in sync with `RoundTripParams` in shaders/field/round_trip_stats.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct RoundTripParams {
    /// Voxels, voxels per chunk (abi::SUM_CHUNK), chunks, unused.
    pub counts: [u32; 4],
    /// Residual (mm) beyond which a voxel counts as far.
    pub far: f32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}

impl RoundTripParams {
    /// Over `voxels` source voxels, counting those farther than `far` mm.
    pub fn new(voxels: usize, far: f32) -> Self {
        RoundTripParams {
            counts: chunking(voxels, SUM_CHUNK, 0),
            far,
            pad: [0; 3],
        }
    }

    /// Chunks, hence [`ROUND_TRIP_WIDTH`] values each.
    pub fn chunks(&self) -> usize {
        self.counts[2] as usize
    }
}
