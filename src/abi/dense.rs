//! Parameters of the dense stage's kernels (shaders/dense/), each with named fields; the
//! WGSL twins pad where they must.

use super::{count, mm_to_index_rows};
use crate::volume::Grid;
use bytemuck::{Pod, Zeroable};

/// Largest Gaussian radius (taps each side of the centre) one smoothing pass takes.
pub const MAX_GAUSS_RADIUS: usize = 31;

/// Largest standard deviation (voxels) a smoothing may ask for: its radius, 3σ, fits.
pub const MAX_GAUSS_SIGMA: f64 = MAX_GAUSS_RADIUS as f64 / 3.0;

/// Voxels per chunk of `norm_max`'s partial maxima.
pub const NORM_CHUNK: usize = 4096;

/// Keep in sync with `GaussParams` in shaders/dense/gauss_axis.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct GaussParams {
    /// Voxels along x.
    pub nx: u32,
    /// Voxels along y.
    pub ny: u32,
    /// Voxels along z.
    pub nz: u32,
    /// Floats per voxel (1 for an image, 3 for a field), smoothed each on its own.
    pub components: u32,
    /// The axis this pass smooths along (0 x, 1 y, 2 z).
    pub axis: u32,
    /// Taps each side of the centre (≤ [`MAX_GAUSS_RADIUS`]).
    pub radius: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 2],
    /// Weight of the taps at offsets 0 ..= radius (the same at ±t), four to a vec4, summing
    /// to 1 over −radius ..= radius.
    pub taps: [[f32; 4]; (MAX_GAUSS_RADIUS + 1) / 4],
}

impl GaussParams {
    /// The three passes (x, y, z) smoothing `components` floats per voxel on `grid` with a
    /// Gaussian of standard deviation `sigma` voxels (0 leaves the values as they are; at most
    /// [`MAX_GAUSS_SIGMA`]), truncated at 3σ and renormalised. A tap past a face reads the
    /// face's voxel.
    pub fn passes(grid: &Grid, components: usize, sigma: f64) -> [GaussParams; 3] {
        let radius = ((3.0 * sigma).ceil() as usize).min(MAX_GAUSS_RADIUS);
        let weight = |t: usize| match sigma > 0.0 {
            true => (-((t * t) as f64) / (2.0 * sigma * sigma)).exp(),
            false => 1.0,
        };
        let total: f64 = (1..=radius).map(|t| 2.0 * weight(t)).sum::<f64>() + weight(0);
        let mut taps = [[0.0f32; 4]; (MAX_GAUSS_RADIUS + 1) / 4];
        for t in 0..=radius {
            taps[t / 4][t % 4] = (weight(t) / total) as f32;
        }
        std::array::from_fn(|axis| GaussParams {
            nx: grid.dims[0] as u32,
            ny: grid.dims[1] as u32,
            nz: grid.dims[2] as u32,
            components: components as u32,
            axis: axis as u32,
            radius: radius as u32,
            pad: [0; 2],
            taps,
        })
    }

    /// Floats written: `components` per voxel.
    pub fn values(&self) -> usize {
        self.components as usize * self.voxels()
    }

    /// Voxels of the grid.
    pub fn voxels(&self) -> usize {
        count(&[self.nx, self.ny, self.nz, 0])
    }

    /// The weight of the tap at offset ±t.
    pub fn tap(&self, t: u32) -> f32 {
        self.taps[t as usize / 4][t as usize % 4]
    }
}

/// The image term a dense force follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ForceTerm {
    /// Sum of squared differences.
    Ssd = 0,
    /// Local (windowed) correlation, squared.
    Lncc = 1,
    /// The volume term: (log det J)² of the whole map, W its determinant (F unused).
    Volume = 2,
}

/// Determinant below which the volume term takes this value instead (its log and the
/// force's 1 / det stay finite where the map folds).
pub const VOLUME_DET_FLOOR: f32 = 0.5;

/// Keep in sync with `ForceParams` in shaders/dense/dense_force.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct ForceParams {
    /// Voxels along x.
    pub nx: u32,
    /// Voxels along y.
    pub ny: u32,
    /// Voxels along z.
    pub nz: u32,
    /// Radius (voxels) of LNCC's windows, (2 r + 1)³ voxels (the box sums' own); unused by SSD.
    pub radius: u32,
    /// The image term: [`ForceTerm`] as a number.
    pub term: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
    /// Rows of the inverse of the grid's linear part: d(index)/d(world mm).
    pub mm_to_index: [[f32; 4]; 3],
}

impl ForceParams {
    /// For images on `grid` compared by `term` (LNCC over windows of `radius` voxels).
    pub fn new(grid: &Grid, term: ForceTerm, radius: usize) -> Self {
        ForceParams {
            nx: grid.dims[0] as u32,
            ny: grid.dims[1] as u32,
            nz: grid.dims[2] as u32,
            radius: radius as u32,
            term: term as u32,
            pad: [0; 3],
            mm_to_index: mm_to_index_rows(grid),
        }
    }

    /// Voxels of the grid.
    pub fn voxels(&self) -> usize {
        count(&[self.nx, self.ny, self.nz, 0])
    }

    /// The grid's dims and the window radius as window.wgsl's `d` takes them.
    pub fn window_dims(&self) -> [u32; 4] {
        [self.nx, self.ny, self.nz, self.radius]
    }
}

/// Keep in sync with `NormParams` in shaders/dense/norm_max.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct NormParams {
    /// Vectors (3 floats each) in the field.
    pub vectors: u32,
    /// Vectors per chunk ([`NORM_CHUNK`]).
    pub per_chunk: u32,
    /// Chunks: one maximum each.
    pub chunks: u32,
    /// Padding to 16 bytes.
    pub pad: u32,
}

impl NormParams {
    /// For a field on `grid`.
    pub fn new(grid: &Grid) -> Self {
        NormParams {
            vectors: grid.len() as u32,
            per_chunk: NORM_CHUNK as u32,
            chunks: grid.len().div_ceil(NORM_CHUNK) as u32,
            pad: 0,
        }
    }
}

/// Keep in sync with `CombineParams` in shaders/dense/field_combine.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct CombineParams {
    /// Voxels along x.
    pub nx: u32,
    /// Voxels along y.
    pub ny: u32,
    /// Voxels along z.
    pub nz: u32,
    /// 1: faded by the distance to the nearest marked voxel (a bone, or a fold); 0: not.
    pub faded: u32,
    /// Factor of the first field.
    pub a_scale: f32,
    /// Factor of the second field.
    pub b_scale: f32,
    /// mm over which the fade rises from 0 on a marked voxel to 1 (> 0 where faded).
    pub margin_mm: f32,
    /// Padding to 16 bytes.
    pub pad: u32,
}

impl CombineParams {
    /// a_scale · a + b_scale · b on `grid`, not faded.
    pub fn sum(grid: &Grid, a_scale: f64, b_scale: f64) -> Self {
        CombineParams {
            nx: grid.dims[0] as u32,
            ny: grid.dims[1] as u32,
            nz: grid.dims[2] as u32,
            faded: 0,
            a_scale: a_scale as f32,
            b_scale: b_scale as f32,
            margin_mm: 0.0,
            pad: 0,
        }
    }

    /// The same, faded to zero on marked voxels (the bones, or where a map folds) over
    /// `margin_mm` (> 0) by the distance to the nearest (images::regions::distance_to_nearest).
    pub fn faded(self, margin_mm: f64) -> Self {
        CombineParams {
            faded: 1,
            margin_mm: margin_mm as f32,
            ..self
        }
    }

    /// Voxels of the grid.
    pub fn voxels(&self) -> usize {
        count(&[self.nx, self.ny, self.nz, 0])
    }
}
