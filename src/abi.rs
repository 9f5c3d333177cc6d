//! Parameter structs shared with the WGSL kernels, byte for byte.
//!
//! Each struct is `#[repr(C)]` Pod with u32/f32/[f32; 4] fields and explicit padding (never a
//! vec3, whose 16-byte alignment differs between Rust and WGSL). Each is mirrored by a struct of
//! the same name in its shader; `tests/shaders.rs` checks the sizes through naga reflection.
//! The constructors do the f64 host-side geometry once, so both backends receive identical f32s.

use crate::error::{Error, Result};
use crate::volume::{Affine, Grid};
use bytemuck::{Pod, Zeroable};

pub mod dense;

/// How the bones' rigid motions are blended across soft tissue.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum Blending {
    /// Σ_j w_j M_j (the paper's linear blend skinning).
    #[default]
    Linear,
    /// The normalised blend of the motions' unit dual quaternions.
    DualQuaternion,
}

/// Bone motions (source → target world) and how to blend and invert them.
#[derive(Clone, Debug)]
pub struct BoneBlend {
    /// One rigid motion per weight bone.
    pub motions: Vec<Affine>,
    /// Linear or dual-quaternion.
    pub blending: Blending,
    /// Newton-like inversion steps per voxel.
    pub iterations: u32,
}

/// Refuses bone counts the skinning kernels cannot take.
pub fn check_bone_count(bones: usize) -> Result<()> {
    if bones == 0 || bones > MAX_SKIN_BONES {
        return Err(Error::InvalidInput(format!(
            "skinning takes 1 to {MAX_SKIN_BONES} bones, got {bones}"
        )));
    }
    Ok(())
}

/// Sums per column of rigid_gn: JᵀJ upper triangle (21), Jᵀr (6), Σr² (1), count (1).
pub const RIGID_SUMS: usize = 29;

/// Sums per column and candidate of rigid_score: Σr², count, ΣS, ΣT, ΣS², ΣT², ΣS·T.
pub const SCORE_SUMS: usize = 7;

/// 12 floats per candidate: rows 0..3 of each matrix (the rigid_score kernel's layout).
pub fn pack_candidates(candidates: &[Affine]) -> Vec<f32> {
    candidates
        .iter()
        .flat_map(|m| (0..3).flat_map(move |r| (0..4).map(move |c| m[(r, c)] as f32)))
        .collect()
}

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

/// Removes the 1e-16-sized noise an f64 inverse leaves on entries that are whole numbers, so a
/// target grid equal to the source grid maps every voxel exactly onto itself.
fn snap_to_integers(m: &Affine) -> Affine {
    m.map(|v| {
        if (v - v.round()).abs() < 1e-9 {
            v.round()
        } else {
            v
        }
    })
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

/// Keep in sync with `LabelCodes` in shaders/labels.wgsl: the label codes a kernel compares
/// labels with (up to [`MAX_SKIN_BONES`]: one per bone).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LabelCodes {
    /// Codes in the list, unused ×3.
    pub count: [u32; 4],
    /// The codes, 4 per row.
    pub list: [[u32; 4]; 2],
}

impl LabelCodes {
    /// The codes `codes`, in order.
    pub fn new(codes: &[u16]) -> Result<Self> {
        if codes.len() > MAX_SKIN_BONES {
            return Err(Error::InvalidInput(format!(
                "a label lookup takes at most {MAX_SKIN_BONES} codes, got {}",
                codes.len()
            )));
        }
        let mut list = [[0u32; 4]; 2];
        for (c, &code) in codes.iter().enumerate() {
            list[c / 4][c % 4] = code as u32;
        }
        Ok(LabelCodes {
            count: [codes.len() as u32, 0, 0, 0],
            list,
        })
    }
}

/// Keep in sync with `LabelParams` in shaders/label_index.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LabelParams {
    /// nx, ny, nz of the label map, unused.
    pub dims: [u32; 4],
    /// The codes whose positions the kernel writes.
    pub codes: LabelCodes,
}

impl LabelParams {
    /// For a label map on `grid`, indexing `codes`.
    pub fn new(grid: &Grid, codes: &[u16]) -> Result<Self> {
        Ok(LabelParams {
            dims: dims4(grid, 0),
            codes: LabelCodes::new(codes)?,
        })
    }

    /// Voxels of the label map.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `BoneLookupParams` in shaders/bone_lookup.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct BoneLookupParams {
    /// Target grid → source label grid, nearest voxel, background −1.
    pub geometry: ResampleParams,
    /// The bones' codes.
    pub codes: LabelCodes,
    /// Largest residual (mm) bone_at_source counts, unused ×3.
    pub limit: [f32; 4],
}

impl BoneLookupParams {
    /// For target voxels on `target` looking up `bones` in a label map on `labels`, counting
    /// voxels whose residual is at most `residual_limit`.
    pub fn new(labels: &Grid, target: &Grid, bones: &[u16], residual_limit: f32) -> Result<Self> {
        Ok(BoneLookupParams {
            geometry: ResampleParams::new(labels, target, -1.0, Interpolation::Nearest),
            codes: LabelCodes::new(bones)?,
            limit: [residual_limit, 0.0, 0.0, 0.0],
        })
    }

    /// Voxels of the target grid.
    pub fn voxels(&self) -> usize {
        self.geometry.voxels()
    }
}

/// Keep in sync with `DilateParams` in shaders/dilate.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct DilateParams {
    /// nx, ny, nz, and the margin (voxels).
    pub dims: [u32; 4],
    /// Axis (0 x, 1 y, 2 z), 1 to clear the held voxels, unused ×2.
    pub axis: [u32; 4],
}

impl DilateParams {
    /// The passes dilating a mask on `grid` by `margin` voxels along x, y and z, the last
    /// clearing the held voxels.
    pub fn passes(grid: &Grid, margin: usize) -> [DilateParams; 3] {
        std::array::from_fn(|axis| DilateParams {
            dims: dims4(grid, margin as u32),
            axis: [axis as u32, (axis == 2) as u32, 0, 0],
        })
    }

    /// Voxels of the grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }
}

/// Local moments per voxel: Σa, Σb, Σa², Σb², Σab over a box window (shaders/local_moments.wgsl).
pub const LOCAL_MOMENTS: usize = 5;

/// Keep in sync with `LocalMomentsParams` in shaders/local_moments.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LocalMomentsParams {
    /// nx, ny, nz, and the window's radius (voxels).
    pub dims: [u32; 4],
    /// Axis of this pass (0 x, 1 y, 2 z), 1 on the first pass (it reads the two images), unused ×2.
    pub axis: [u32; 4],
}

impl LocalMomentsParams {
    /// The x, y and z passes summing two images' [`LOCAL_MOMENTS`] on `grid` over a box of
    /// (2 `radius` + 1)³ voxels (cut at the grid's faces).
    pub fn passes(grid: &Grid, radius: usize) -> [LocalMomentsParams; 3] {
        std::array::from_fn(|axis| LocalMomentsParams {
            dims: dims4(grid, radius as u32),
            axis: [axis as u32, (axis == 0) as u32, 0, 0],
        })
    }

    /// The x, y and z passes summing a stack of [`LOCAL_MOMENTS`] values per voxel on `grid`
    /// (as lncc_terms writes) over the same boxes.
    pub fn stack_passes(grid: &Grid, radius: usize) -> [LocalMomentsParams; 3] {
        std::array::from_fn(|axis| LocalMomentsParams {
            dims: dims4(grid, radius as u32),
            axis: [axis as u32, 0, 0, 0],
        })
    }

    /// Values written: [`LOCAL_MOMENTS`] per voxel.
    pub fn values(&self) -> usize {
        LOCAL_MOMENTS * count(&self.dims)
    }
}

/// Keep in sync with `LnccTermsParams` in shaders/lncc_terms.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LnccTermsParams {
    /// nx, ny, nz, and the window's radius (voxels).
    pub dims: [u32; 4],
    /// The cost's scale K, unused ×3.
    pub scale: [f32; 4],
}

impl LnccTermsParams {
    /// For [`LOCAL_MOMENTS`] summed on `grid` over windows of `radius` voxels; the cost is
    /// `scale` Σ c (1 − ρ²).
    pub fn new(grid: &Grid, radius: usize, scale: f32) -> Self {
        LnccTermsParams {
            dims: dims4(grid, radius as u32),
            scale: [scale, 0.0, 0.0, 0.0],
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

/// Keep in sync with `LnccParams` in shaders/lncc.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LnccParams {
    /// nx, ny, nz, and the window's radius (voxels).
    pub dims: [u32; 4],
    /// Voxels, voxels per chunk ([`STATS_CHUNK`]), chunks, unused.
    pub chunks: [u32; 4],
}

impl LnccParams {
    /// For [`LOCAL_MOMENTS`] summed on `grid` over windows of `radius` voxels.
    pub fn new(grid: &Grid, radius: usize) -> Self {
        LnccParams {
            dims: dims4(grid, radius as u32),
            chunks: chunking(grid.len(), STATS_CHUNK, 0),
        }
    }

    /// Chunks the kernel writes 2 values for.
    pub fn chunks(&self) -> usize {
        self.chunks[2] as usize
    }
}

/// Longest line an edt pass takes: the shader keeps a line's envelope in private arrays.
pub const MAX_EDT_LINE: usize = 1024;

/// Keep in sync with `EdtParams` in shaders/edt.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct EdtParams {
    /// nx, ny, nz, and the axis of this pass (0 x, 1 y, 2 z).
    pub dims: [u32; 4],
    /// mm between samples along x, y, z, unused.
    pub spacing: [f32; 4],
    /// Volumes in the stack, 1 on the first pass (its input is one volume whose values round to
    /// the stack index + 1 on each region), 1 on the last (square roots), unused.
    pub stack: [u32; 4],
}

impl EdtParams {
    /// The x, y and z passes of the distance maps (mm) on `grid` to the regions 1 ..= `volumes`
    /// of a label index map (or, for one volume, of a 0/1 indicator); refuses grids with a
    /// line longer than [`MAX_EDT_LINE`].
    pub fn passes(grid: &Grid, volumes: usize) -> Result<[EdtParams; 3]> {
        if let Some(&longest) = grid.dims.iter().max().filter(|&&n| n > MAX_EDT_LINE) {
            return Err(Error::InvalidInput(format!(
                "distance maps take grids of at most {MAX_EDT_LINE} voxels along an axis, got {longest}"
            )));
        }
        let h = grid.spacing();
        Ok(std::array::from_fn(|axis| EdtParams {
            dims: dims4(grid, axis as u32),
            spacing: [h[0] as f32, h[1] as f32, h[2] as f32, 0.0],
            stack: [volumes as u32, (axis == 0) as u32, (axis == 2) as u32, 0],
        }))
    }

    /// Values written: volumes × voxels.
    pub fn values(&self) -> usize {
        self.stack[0] as usize * count(&self.dims)
    }

    /// Lines along the other two axes (each a workgroup dimension).
    pub fn lines(&self) -> [usize; 2] {
        let d = self.dims.map(|n| n as usize);
        match d[3] {
            0 => [d[1], d[2]],
            1 => [d[0], d[2]],
            _ => [d[0], d[1]],
        }
    }
}

/// Keep in sync with `MomentsParams` in shaders/moments.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct MomentsParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Voxels, voxels per chunk ([`STATS_CHUNK`]), chunks, unused.
    pub chunks: [u32; 4],
    /// Value at or above which a voxel counts, unused ×3.
    pub threshold: [f32; 4],
    /// Voxel index → world (mm).
    pub index_to_world: [[f32; 4]; 3],
}

impl MomentsParams {
    /// For the voxels of a map on `grid` at or above `threshold`.
    pub fn new(grid: &Grid, threshold: f32) -> Self {
        MomentsParams {
            dims: dims4(grid, 0),
            chunks: chunking(grid.len(), STATS_CHUNK, 0),
            threshold: [threshold, 0.0, 0.0, 0.0],
            index_to_world: rows(&grid.affine),
        }
    }

    /// Chunks the kernel writes 4 values for.
    pub fn chunks(&self) -> usize {
        self.chunks[2] as usize
    }
}

/// Voxels per chunk of the fold statistics and the moments.
pub const STATS_CHUNK: usize = 1024;
/// Floats of fold statistics per chunk (shaders/fold_stats.wgsl): minimum, folded, at most the
/// threshold, of those not held, folded bone contacts.
pub const FOLD_STATS_WIDTH: usize = 5;

/// Keep in sync with `ThresholdParams` in shaders/threshold.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct ThresholdParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Voxels, voxels per chunk ([`STATS_CHUNK`]), chunks, unused.
    pub chunks: [u32; 4],
    /// The threshold (det J for the folds, mm for a distance), unused ×3.
    pub threshold: [f32; 4],
}

impl ThresholdParams {
    /// For a value per voxel of `grid` compared with `threshold`.
    pub fn new(grid: &Grid, threshold: f32) -> Self {
        ThresholdParams {
            dims: dims4(grid, 0),
            chunks: chunking(grid.len(), STATS_CHUNK, 0),
            threshold: [threshold, 0.0, 0.0, 0.0],
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

/// Keep in sync with `JacobianParams` in shaders/jacobian.wgsl.
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

/// Keep in sync with `InvertParams` in shaders/invert_field.wgsl.
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

/// Rows 0..3 of a 4×4 affine as f32 [x, y, z, w] (w = translation).
fn rows(m: &Affine) -> [[f32; 4]; 3] {
    std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)] as f32))
}

/// Rows of the linear part only (w = 0).
fn linear_rows(m: &nalgebra::Matrix3<f64>) -> [[f32; 4]; 3] {
    std::array::from_fn(|r| [m[(r, 0)] as f32, m[(r, 1)] as f32, m[(r, 2)] as f32, 0.0])
}

/// Rows of the inverse of `grid`'s linear part (d(index)/d(world mm)), whole numbers snapped.
fn mm_to_index_rows(grid: &Grid) -> [[f32; 4]; 3] {
    let inv = snap_to_integers(&grid.world_to_voxel_affine());
    std::array::from_fn(|r| {
        [
            inv[(r, 0)] as f32,
            inv[(r, 1)] as f32,
            inv[(r, 2)] as f32,
            0.0,
        ]
    })
}

/// nx · ny · nz of a parameter struct's [nx, ny, nz, _].
fn count(dims: &[u32; 4]) -> usize {
    dims[..3].iter().map(|&n| n as usize).product()
}

/// [values, values per chunk, chunks, w]: how a reduction splits `values` into chunks.
fn chunking(values: usize, per_chunk: usize, w: u32) -> [u32; 4] {
    [
        values as u32,
        per_chunk as u32,
        values.div_ceil(per_chunk) as u32,
        w,
    ]
}

fn dims4(g: &Grid, w: u32) -> [u32; 4] {
    padded(g.dims, w)
}

/// Three counts as a vec4<u32>, `w` last.
fn padded(v: [usize; 3], w: u32) -> [u32; 4] {
    [v[0] as u32, v[1] as u32, v[2] as u32, w]
}

/// Keep in sync with `PyramidParams` in shaders/pyramid.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct PyramidParams {
    /// Output nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Input nx, ny, nz, unused.
    pub input_dims: [u32; 4],
    /// 1 or 2 per axis, unused.
    pub factors: [u32; 4],
}

impl PyramidParams {
    /// From the input grid, the output dims and the per-axis factors.
    pub fn new(input: &Grid, output_dims: [usize; 3], factors: [usize; 3]) -> Self {
        PyramidParams {
            dims: [
                output_dims[0] as u32,
                output_dims[1] as u32,
                output_dims[2] as u32,
                0,
            ],
            input_dims: dims4(input, 0),
            factors: [factors[0] as u32, factors[1] as u32, factors[2] as u32, 0],
        }
    }

    /// Voxels of the output level.
    pub fn output_len(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `RigidParams` in shaders/rigid_gn.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct RigidParams {
    /// Source nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Target nx, ny, nz, unused.
    pub target_dims: [u32; 4],
    /// Source voxel index → target continuous index under the current motion.
    pub to_target_index: [[f32; 4]; 3],
    /// Source voxel index → moved world point minus the rotation centre.
    pub to_centred_world: [[f32; 4]; 3],
    /// Target index-space gradient → world gradient ((L_t⁻¹)ᵀ).
    pub gradient_to_world: [[f32; 4]; 3],
}

impl RigidParams {
    /// For motion `m` (source world → target world) linearised about `centre` (target world).
    pub fn new(source: &Grid, target: &Grid, m: &Affine, centre: [f64; 3]) -> Self {
        let to_target = target.world_to_voxel_affine() * m * source.affine;
        let mut centred = m * source.affine;
        for r in 0..3 {
            centred[(r, 3)] -= centre[r];
        }
        let lt: nalgebra::Matrix3<f64> = target.affine.fixed_view::<3, 3>(0, 0).into_owned();
        let grad = lt
            .try_inverse()
            .expect("validated grids are invertible")
            .transpose();
        RigidParams {
            dims: dims4(source, 0),
            target_dims: dims4(target, 0),
            to_target_index: rows(&to_target),
            to_centred_world: rows(&centred),
            gradient_to_world: linear_rows(&grad),
        }
    }

    /// Columns of the source (one partial result each): nx · nz.
    pub fn columns(&self) -> usize {
        self.dims[0] as usize * self.dims[2] as usize
    }
}

/// Keep in sync with `ScoreParams` in shaders/rigid_score.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct ScoreParams {
    /// Source nx, ny, nz, number of candidates.
    pub dims: [u32; 4],
    /// Target nx, ny, nz, unused.
    pub target_dims: [u32; 4],
    /// Source voxel index → world.
    pub source_to_world: [[f32; 4]; 3],
    /// World → target continuous index.
    pub world_to_target: [[f32; 4]; 3],
}

impl ScoreParams {
    /// For `candidates` motions of a bone from `source` into `target`.
    pub fn new(source: &Grid, target: &Grid, candidates: usize) -> Self {
        ScoreParams {
            dims: dims4(source, candidates as u32),
            target_dims: dims4(target, 0),
            source_to_world: rows(&source.affine),
            world_to_target: rows(&target.world_to_voxel_affine()),
        }
    }

    /// Columns of the source (one partial result per candidate each): nx · nz.
    pub fn columns(&self) -> usize {
        self.dims[0] as usize * self.dims[2] as usize
    }

    /// Candidate motions scored.
    pub fn candidates(&self) -> usize {
        self.dims[3] as usize
    }
}

/// Keep in sync with `SkinWeightsParams` in shaders/skin_weights.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SkinWeightsParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Bones, Shepard power, unused ×2.
    pub weights: [u32; 4],
    /// Per bone, the factor its distances are scaled by (skinning::reach_scale), 4 per row.
    pub reach: [[f32; 4]; 2],
}

impl SkinWeightsParams {
    /// Weights on `grid` with Shepard exponent `power`, one bone per entry of `reach` (at most
    /// [`MAX_SKIN_BONES`]).
    pub fn new(grid: &Grid, reach: &[f32], power: u32) -> Self {
        assert!(reach.len() <= MAX_SKIN_BONES, "checked by the caller");
        let mut rows = [[0.0f32; 4]; 2];
        for (j, &r) in reach.iter().enumerate() {
            rows[j / 4][j % 4] = r;
        }
        SkinWeightsParams {
            dims: dims4(grid, 0),
            weights: [reach.len() as u32, power, 0, 0],
            reach: rows,
        }
    }

    /// Weights written: bones per voxel.
    pub fn values(&self) -> usize {
        count(&self.dims) * self.weights[0] as usize
    }
}

/// Most bones a skinning kernel takes (its matrices live in the uniform).
pub const MAX_SKIN_BONES: usize = 8;

/// Keep in sync with `SkinBlendParams` in shaders/skin_blend.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SkinBlendParams {
    /// Target nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Bones, inversion iterations, blending (0 linear, 1 dual quaternion), unused.
    pub blend: [u32; 4],
    /// Weight grid nx, ny, nz, unused.
    pub weight_dims: [u32; 4],
    /// Source label grid nx, ny, nz, unused.
    pub label_dims: [u32; 4],
    /// Target voxel index → world.
    pub target_to_world: [[f32; 4]; 3],
    /// World → weight-grid continuous index.
    pub world_to_weight: [[f32; 4]; 3],
    /// World → source label grid continuous index.
    pub world_to_label: [[f32; 4]; 3],
    /// Three rows of M_j per bone (source → target world).
    pub forward: [[f32; 4]; 3 * MAX_SKIN_BONES],
    /// Three rows of M_j⁻¹ per bone.
    pub inverse: [[f32; 4]; 3 * MAX_SKIN_BONES],
    /// Unit dual quaternion of M_j per bone: real part (x, y, z, w), then dual part.
    pub dual: [[f32; 4]; 2 * MAX_SKIN_BONES],
}

impl SkinBlendParams {
    /// Voxels of the target grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }

    /// For bones moving as `blend` says (at most [`MAX_SKIN_BONES`]), weights on `weights`,
    /// bone labels on `labels`.
    pub fn new(target: &Grid, weights: &Grid, labels: &Grid, blend: &BoneBlend) -> Self {
        let motions = &blend.motions;
        assert!(motions.len() <= MAX_SKIN_BONES, "checked by the caller");
        let mut forward = [[0.0f32; 4]; 3 * MAX_SKIN_BONES];
        let mut inverse = [[0.0f32; 4]; 3 * MAX_SKIN_BONES];
        let mut dual = [[0.0f32; 4]; 2 * MAX_SKIN_BONES];
        for (j, m) in motions.iter().enumerate() {
            let inv = m.try_inverse().unwrap_or_else(Affine::identity);
            forward[3 * j..3 * j + 3].copy_from_slice(&rows(m));
            inverse[3 * j..3 * j + 3].copy_from_slice(&rows(&inv));
            dual[2 * j..2 * j + 2].copy_from_slice(&dual_quaternion(m));
        }
        let blending = match blend.blending {
            Blending::Linear => 0,
            Blending::DualQuaternion => 1,
        };
        SkinBlendParams {
            dims: dims4(target, 0),
            blend: [motions.len() as u32, blend.iterations, blending, 0],
            weight_dims: dims4(weights, 0),
            label_dims: dims4(labels, 0),
            target_to_world: rows(&target.affine),
            world_to_weight: rows(&weights.world_to_voxel_affine()),
            world_to_label: rows(&labels.world_to_voxel_affine()),
            forward,
            inverse,
            dual,
        }
    }
}

/// The unit dual quaternion (real part, dual part; each x, y, z, w) of a rigid motion, real
/// part in the w ≥ 0 hemisphere: every motion is then on the identity's side, so blending with
/// a bone that barely moves (the femur) takes the short way round for turns below 180°.
fn dual_quaternion(m: &Affine) -> [[f32; 4]; 2] {
    let rotation = nalgebra::Rotation3::from_matrix(&m.fixed_view::<3, 3>(0, 0).into_owned());
    let mut real = nalgebra::UnitQuaternion::from_rotation_matrix(&rotation).into_inner();
    if real.w < 0.0 {
        real = -real;
    }
    let t = nalgebra::Quaternion::from_imag(m.fixed_view::<3, 1>(0, 3).into_owned());
    let dual = t * real * 0.5;
    let q = |q: nalgebra::Quaternion<f64>| [q.i as f32, q.j as f32, q.k as f32, q.w as f32];
    [q(real), q(dual)]
}

/// Keep in sync with `RbfGradParams` in shaders/lattice_warp.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct RbfGradParams {
    /// Target nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Lattice nodes along x, y, z, unused.
    pub lattice_dims: [u32; 4],
    /// Lattice step along x, y, z (voxels: node a sits on voxel a · step), unused.
    pub lattice_step: [u32; 4],
    /// Rows of the inverse linear part of the grid: a displacement in mm → index delta.
    pub mm_to_index: [[f32; 4]; 3],
    /// Index-space gradient → world gradient ((L⁻¹)ᵀ).
    pub gradient_to_world: [[f32; 4]; 3],
}

impl RbfGradParams {
    /// For a target `grid` with a lattice of `lattice_dims` nodes every `steps` voxels.
    pub fn new(grid: &Grid, lattice_dims: [usize; 3], steps: [usize; 3]) -> Self {
        let l: nalgebra::Matrix3<f64> = grid.affine.fixed_view::<3, 3>(0, 0).into_owned();
        let inv = l.try_inverse().expect("validated grids are invertible");
        RbfGradParams {
            dims: dims4(grid, 0),
            lattice_dims: padded(lattice_dims, 0),
            lattice_step: padded(steps, 0),
            mm_to_index: linear_rows(&inv),
            gradient_to_world: linear_rows(&inv.transpose()),
        }
    }

    /// Voxels of the target grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }

    /// Rows of x (ny · nz): warp_cost writes one sum per row.
    pub fn rows(&self) -> usize {
        (self.dims[1] * self.dims[2]) as usize
    }
}

/// Keep in sync with `SplatParams` in shaders/lattice_splat.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SplatParams {
    /// Lattice lx, ly, lz, unused.
    pub dims: [u32; 4],
    /// Lattice step along x, y, z (voxels), unused.
    pub step: [u32; 4],
    /// Volume nx, ny, nz, unused.
    pub volume_dims: [u32; 4],
}

impl SplatParams {
    /// For a lattice of `lattice_dims` nodes every `steps` voxels over a volume of `dims`.
    pub fn new(lattice_dims: [usize; 3], steps: [usize; 3], dims: [usize; 3]) -> Self {
        SplatParams {
            dims: padded(lattice_dims, 0),
            step: padded(steps, 0),
            volume_dims: padded(dims, 0),
        }
    }

    /// Nodes of the lattice.
    pub fn nodes(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `RbfLatticeParams` in shaders/rbf_nodes.wgsl (rbf_lattice, rbf_adjoint).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct RbfLatticeParams {
    /// Lattice nodes along x, y, z, and the number of control points.
    pub lattice: [u32; 4],
    /// Lattice step along x, y, z (voxels), unused.
    pub step: [u32; 4],
    /// rbf_adjoint's chunks: nodes, nodes per chunk, chunks, unused.
    pub chunks: [u32; 4],
}

/// Lattice nodes one rbf_adjoint invocation sums: about `nodes / 512`, so that a GPU runs
/// hundreds of chunks side by side (with 4096 nodes a chunk, the paper-size lattice made 37
/// chunks and each invocation a serial loop of f64 square roots: 2.7 ms of an evaluation's
/// 4.1 ms on an NVIDIA H200), but at least 256 (fewer partials to add) and at most 4096 (well
/// below lavapipe's 65 535 loop iterations).
fn adjoint_chunk(nodes: usize) -> usize {
    (nodes / 512).clamp(256, 4096)
}

impl RbfLatticeParams {
    /// A lattice of `lattice_dims` nodes every `steps` voxels, for a warp of `points` control
    /// points.
    pub fn new(lattice_dims: [usize; 3], steps: [usize; 3], points: usize) -> Self {
        let nodes: usize = lattice_dims.iter().product();
        RbfLatticeParams {
            lattice: padded(lattice_dims, points as u32),
            step: padded(steps, 0),
            chunks: chunking(nodes, adjoint_chunk(nodes), 0),
        }
    }

    /// Nodes per chunk of rbf_adjoint.
    pub fn chunk_nodes(&self) -> usize {
        self.chunks[1] as usize
    }

    /// Chunks of nodes rbf_adjoint sums separately.
    pub fn chunks(&self) -> usize {
        self.chunks[2] as usize
    }

    /// rbf_adjoint's output rows: the control points, then 4 affine rows.
    pub fn rows(&self) -> usize {
        self.points() + 4
    }

    /// Nodes in the lattice.
    pub fn nodes(&self) -> usize {
        count(&self.lattice)
    }

    /// Control points.
    pub fn points(&self) -> usize {
        self.lattice[3] as usize
    }
}

/// The rows of `grid`'s voxel → world affine as the RBF kernels read them (`geometry`, 12 f64).
pub fn lattice_geometry(grid: &Grid) -> Vec<f64> {
    (0..3)
        .flat_map(|r| (0..4).map(move |c| grid.affine[(r, c)]))
        .collect()
}

/// The cubic RBF as the RBF kernels read it (`spline`): the affine part a_kc at 3k + c, then
/// per control point its position and λ.
pub fn spline_buffer(
    affine: &[[f64; 3]; 4],
    centres: &[[f64; 3]],
    lambda: &[[f64; 3]],
) -> Vec<f64> {
    let mut out: Vec<f64> = affine.iter().flatten().copied().collect();
    for (c, l) in centres.iter().zip(lambda) {
        out.extend_from_slice(c);
        out.extend_from_slice(l);
    }
    out
}

/// Values per chunk of sum_chunks.
pub const SUM_CHUNK: usize = 1024;

/// Keep in sync with `SumParams` in shaders/sum_chunks.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SumParams {
    /// Values, values per chunk, chunks, power (1 or 2).
    pub counts: [u32; 4],
    /// Shift subtracted from each value before the power, unused ×3.
    pub shift: [f32; 4],
}

impl SumParams {
    /// Sums of `values` values in chunks of [`SUM_CHUNK`].
    pub fn new(values: usize) -> Self {
        SumParams {
            counts: chunking(values, SUM_CHUNK, 1),
            shift: [0.0; 4],
        }
    }

    /// Sums of the squares of `values` values minus `shift`.
    pub fn squares_about(values: usize, shift: f32) -> Self {
        let mut p = SumParams::new(values);
        p.counts[3] = 2;
        p.shift[0] = shift;
        p
    }

    /// Values summed.
    pub fn values(&self) -> usize {
        self.counts[0] as usize
    }

    /// Chunks, hence sums.
    pub fn chunks(&self) -> usize {
        self.counts[2] as usize
    }
}

/// Most operators of a lattice energy (3 membrane + 6 bending).
pub const MAX_OPERATORS: usize = 9;
/// Most taps of one operator.
pub const MAX_TAPS: usize = 4;

/// One quadratic operator of a lattice energy: taps (node offset, coefficient) and a weight.
#[derive(Clone, Debug, PartialEq)]
pub struct Operator {
    /// Node offsets and coefficients.
    pub taps: Vec<([i32; 3], f32)>,
    /// Weight of the squared result.
    pub weight: f32,
}

/// Keep in sync with `EnergyParams` in shaders/lattice_energy.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct EnergyParams {
    /// Lattice nodes along x, y, z, and the number of operators.
    pub dims: [u32; 4],
    /// Factor on the splatted image gradient (1 / voxels), unused ×3.
    pub scale: [f32; 4],
    /// Operator o's tap t at 4 o + t: node offset, unused.
    pub taps: [[i32; 4]; MAX_OPERATORS * MAX_TAPS],
    /// Operator o's tap coefficients.
    pub coefficients: [[f32; 4]; MAX_OPERATORS],
    /// Operator o's weight, unused ×3.
    pub weights: [[f32; 4]; MAX_OPERATORS],
    /// Operator o's number of taps at [o / 4][o % 4].
    pub tap_counts: [[u32; 4]; 3],
}

impl EnergyParams {
    /// For a lattice of `dims` nodes, splatted gradients scaled by `scale`, and `operators`
    /// (at most [`MAX_OPERATORS`], each with at most [`MAX_TAPS`] taps).
    pub fn new(dims: [usize; 3], scale: f32, operators: &[Operator]) -> Self {
        assert!(
            operators.len() <= MAX_OPERATORS,
            "too many energy operators"
        );
        let mut p = EnergyParams::zeroed();
        p.dims = [
            dims[0] as u32,
            dims[1] as u32,
            dims[2] as u32,
            operators.len() as u32,
        ];
        p.scale[0] = scale;
        for (o, op) in operators.iter().enumerate() {
            assert!(
                op.taps.len() <= MAX_TAPS,
                "too many taps in an energy operator"
            );
            // The CPU twin keeps results only for anchors on the lattice.
            assert!(
                (0..3).all(|a| {
                    let span = op.taps.iter().map(|(offset, _)| offset[a]);
                    span.clone().min() <= Some(0) && span.max() >= Some(0)
                }),
                "an energy operator's anchor must lie within its taps' span"
            );
            for (t, (offset, c)) in op.taps.iter().enumerate() {
                p.taps[MAX_TAPS * o + t] = [offset[0], offset[1], offset[2], 0];
                p.coefficients[o][t] = *c;
            }
            p.weights[o][0] = op.weight;
            p.tap_counts[o / 4][o % 4] = op.taps.len() as u32;
        }
        p
    }

    /// Lattice nodes.
    pub fn nodes(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `PartialsParams` in shaders/sum_partials.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct PartialsParams {
    /// Values per chunk, chunks, chunks per group, unused.
    pub counts: [u32; 4],
}

/// Most chunks one sum_partials invocation adds.
pub const PARTIALS_GROUP: usize = 1024;

impl PartialsParams {
    /// The passes that add `chunks` partial results of `values` values each down to one: each
    /// adds groups of up to [`PARTIALS_GROUP`] chunks, and the next adds its groups.
    pub fn passes(values: usize, chunks: usize) -> Vec<PartialsParams> {
        let mut passes = Vec::new();
        let mut chunks = chunks.max(1);
        loop {
            let group = chunks.min(PARTIALS_GROUP);
            passes.push(PartialsParams {
                counts: [values as u32, chunks as u32, group as u32, 0],
            });
            if group == chunks {
                return passes;
            }
            chunks = chunks.div_ceil(group);
        }
    }

    /// Values per chunk.
    pub fn values(&self) -> usize {
        self.counts[0] as usize
    }

    /// Groups this pass writes (values each).
    pub fn groups(&self) -> usize {
        (self.counts[1] as usize).div_ceil(self.counts[2].max(1) as usize)
    }
}

/// Keep in sync with `FadeParams` in shaders/fade_warp.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct FadeParams {
    /// nx, ny, nz of the warp's grid, and the bones (volumes of the distance stack).
    pub dims: [u32; 4],
    /// mm over which the warp rises from zero on a bone to its whole, unused ×3.
    pub margin: [f32; 4],
}

impl FadeParams {
    /// For a warp on `grid` faded over `margin_mm` (> 0) from `bones` bones.
    pub fn new(grid: &Grid, bones: usize, margin_mm: f64) -> Self {
        FadeParams {
            dims: dims4(grid, bones as u32),
            margin: [margin_mm as f32, 0.0, 0.0, 0.0],
        }
    }

    /// Voxels of the grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `ComposeParams` in shaders/compose.wgsl.
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
