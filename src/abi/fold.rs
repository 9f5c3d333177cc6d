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

/// Which voxels a pass of the fold push leaves (abi::CandidateParams::spared).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Spared {
    /// The voxels whose six stencil neighbours all lie in bones, two different ones.
    EnclosedByBones = 1,
    /// Every bone contact (shaders/fold/contacts.wgsl).
    Contacts = 2,
}

/// Keep in sync with `CandidateParams` in shaders/fold/fold_candidates.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct CandidateParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// det J at or below which a voxel is lifted.
    pub threshold: f32,
    /// [`Spared`] as a number.
    pub spared: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 2],
}

impl CandidateParams {
    /// The voxels of `grid` at or below `threshold`, those `spared` aside.
    pub fn new(grid: &Grid, threshold: f32, spared: Spared) -> Self {
        CandidateParams {
            dims: dims4(grid, 0),
            threshold,
            spared: spared as u32,
            pad: [0; 2],
        }
    }

    /// Voxels of the grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `PushParams` in shaders/fold/fold_push.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct PushParams {
    /// The field's grid → the source label grid (bone_lookup.wgsl's).
    pub geometry: ResampleParams,
    /// The bones' codes.
    pub codes: LabelCodes,
    /// nx, ny, nz of the field's grid, unused.
    pub dims: [u32; 4],
    /// Rows of the inverse of the grid's linear part: d(index)/d(world mm).
    pub mm_to_index: [[f32; 4]; 3],
    /// The colour pushed (shaders/fold/push_list.wgsl); the sweep and how many of its
    /// voxels there are come from the push's state.
    pub colour: u32,
    /// Padding.
    pub pad0: [u32; 3],
    /// Longest move of one neighbour in one push (mm).
    pub largest_step: f32,
    /// det J at or below which a voxel is pushed.
    pub threshold: f32,
    /// det J a push aims for.
    pub aim: f32,
    /// Padding to 16 bytes.
    pub pad1: u32,
}

impl PushParams {
    /// The pushes of colour `colour`'s voxels on `grid`, bones looked up by `lookup`;
    /// `(threshold, target)` the determinants pushed and aimed for.
    pub fn new(
        lookup: &BoneLookupParams,
        grid: &Grid,
        colour: u32,
        (threshold, target): (f32, f32),
    ) -> Self {
        PushParams {
            geometry: lookup.geometry,
            codes: lookup.codes,
            dims: dims4(grid, 0),
            mm_to_index: mm_to_index_rows(grid),
            colour,
            pad0: [0; 3],
            largest_step: grid.finest_spacing() as f32 / 4.0,
            threshold,
            aim: target,
            pad1: 0,
        }
    }
}

/// Keep in sync with `RefreshParams` in shaders/fold/fold_refresh.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct RefreshParams {
    /// nx, ny, nz of the field's grid, unused.
    pub dims: [u32; 4],
    /// Rows of the inverse of the grid's linear part: d(index)/d(world mm).
    pub mm_to_index: [[f32; 4]; 3],
    /// [`Spared`] as a number.
    pub spared: u32,
    /// det J at or below which a voxel is lifted.
    pub threshold: f32,
    /// Padding to 16 bytes.
    pub pad: [u32; 2],
}

impl RefreshParams {
    /// On `grid`, for the pass that spares `spared`.
    pub fn new(grid: &Grid, threshold: f32, spared: Spared) -> Self {
        RefreshParams {
            dims: dims4(grid, 0),
            mm_to_index: mm_to_index_rows(grid),
            spared: spared as u32,
            threshold,
            pad: [0; 2],
        }
    }
}

/// Keep in sync with `AdvanceParams` in shaders/fold/fold_advance.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct AdvanceParams {
    /// The pass ends after these sweeps.
    pub most_sweeps: u32,
    /// ... or after these sweeps in a row have left only bone contacts to lift.
    pub contacts_alone: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 2],
}

impl AdvanceParams {
    /// A pass of at most `most_sweeps`, ended after `contacts_alone` that leave only bone
    /// contacts.
    pub fn new(most_sweeps: usize, contacts_alone: usize) -> Self {
        AdvanceParams {
            most_sweeps: most_sweeps as u32,
            contacts_alone: contacts_alone as u32,
            pad: [0; 2],
        }
    }
}

/// The fold push's state on the device, one u32 each (shaders/fold/push_list.wgsl has the
/// layout and says what each holds).
pub mod push_state {
    /// The sweep under way, from 1.
    pub const SWEEP: usize = 0;
    /// 1 once the pass has ended.
    pub const STOPPED: usize = 1;
    /// Sweeps in a row that left only bone contacts.
    pub const CONTACTS_ALONE: usize = 2;
    /// Voxels of the next list that are not bone contacts.
    pub const LIFTED: usize = 3;
    /// 27 counts: this sweep's list, by colour.
    pub const CURRENT: usize = 4;
    /// 27 counts: the next sweep's list, by colour.
    pub const NEXT: usize = 31;
    /// The colours (i mod 3 + 3 (j mod 3) + 9 (k mod 3)).
    pub const COLOURS: usize = 27;
    /// Invocations per workgroup of the list kernels.
    pub const GROUP: u32 = 64;
    /// Workgroups per row of a list dispatch.
    pub const ROW_GROUPS: u32 = 32768;
    /// The state's length.
    pub const LEN: usize = NEXT + COLOURS;
    /// The length of the workgroup counts of a sweep's dispatches (a buffer apart from the
    /// state): x, y, z for each colour's push, then for the refresh.
    pub const ARGS_LEN: usize = 3 * (COLOURS + 1);
}
