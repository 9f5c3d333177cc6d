//! Parameter structs shared with the WGSL kernels, byte for byte.
//!
//! Each struct is `#[repr(C)]` Pod with u32/f32/[f32; 4] fields and explicit padding (never a
//! vec3, whose 16-byte alignment differs between Rust and WGSL). Each is mirrored by a struct of
//! the same name in its shader; `tests/shaders.rs` checks the sizes through naga reflection.
//! The constructors do the f64 host-side geometry once, so both backends receive identical f32s.

use crate::gpu::run::SlabParams;
use crate::volume::{Affine, Grid};
use bytemuck::{Pod, Zeroable};

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
    /// Target nx, ny, nz, and the first slice of this slab.
    pub target_dims: [u32; 4],
    /// Source nx, ny, nz, and the number of slices in this slab.
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
                target.dims[2] as u32,
            ],
            index_to_source: std::array::from_fn(|r| row(&combined, r, true)),
            mm_to_source: std::array::from_fn(|r| row(&linear, r, false)),
            background,
            nearest: (interpolation == Interpolation::Nearest) as u32,
            pad: [0; 2],
        }
    }
}

impl SlabParams for ResampleParams {
    fn for_slab(&self, z0: u32, depth: u32, _first: u32) -> Self {
        let mut p = *self;
        p.target_dims[3] = z0;
        p.source_dims[3] = depth;
        p
    }
}

/// Keep in sync with `SsdParams` in shaders/ssd_cells.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SsdParams {
    /// nx, ny, slices in this slab, unused.
    pub dims: [u32; 4],
    /// Cells along x, y, z, unused.
    pub cells: [u32; 4],
}

impl SsdParams {
    /// Parameters for a slab of `depth` slices of an (nx, ny, ·) volume split into `cells`.
    pub fn new(dims: [usize; 3], cells: [usize; 3], depth: usize) -> Self {
        SsdParams {
            dims: [dims[0] as u32, dims[1] as u32, depth as u32, 0],
            cells: [cells[0] as u32, cells[1] as u32, cells[2] as u32, 0],
        }
    }
}

impl SlabParams for SsdParams {
    fn for_slab(&self, _z0: u32, depth: u32, _first: u32) -> Self {
        let mut p = *self;
        p.dims[2] = depth;
        p
    }
}

/// Keep in sync with `JacobianParams` in shaders/jacobian.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct JacobianParams {
    /// nx, ny, nz of the field's grid, and the first slice of this slab.
    pub dims: [u32; 4],
    /// Slices in this slab, the slab's first slice held in the bound field buffer (the slab
    /// plus a one-slice halo on each side where the volume has one), unused ×2.
    pub slab: [u32; 4],
    /// Rows of the inverse of the grid's linear part: d(index)/d(world mm).
    pub mm_to_index: [[f32; 4]; 3],
}

impl JacobianParams {
    /// Parameters for the Jacobian of a field on `grid` (whole volume as one slab).
    pub fn new(grid: &Grid) -> Self {
        let inv = snap_to_integers(&grid.world_to_voxel_affine());
        JacobianParams {
            dims: [
                grid.dims[0] as u32,
                grid.dims[1] as u32,
                grid.dims[2] as u32,
                0,
            ],
            slab: [grid.dims[2] as u32, 0, 0, 0],
            mm_to_index: std::array::from_fn(|r| {
                [
                    inv[(r, 0)] as f32,
                    inv[(r, 1)] as f32,
                    inv[(r, 2)] as f32,
                    0.0,
                ]
            }),
        }
    }
}

impl SlabParams for JacobianParams {
    fn for_slab(&self, z0: u32, depth: u32, first: u32) -> Self {
        let mut p = *self;
        p.dims[3] = z0;
        p.slab = [depth, first, 0, 0];
        p
    }
}
