//! Sampling images: through a displacement field, the field's coverage of the source, and
//! pyramid levels.

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

/// Keep in sync with `ResampleParams` in shaders/sampling/resample.wgsl.
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

/// Coverage at or above which a voxel of the moving image holds data from the source scan
/// (`is_covered` in shaders/common.wgsl): 0 or 1 at the finest level, fractional after the
/// pyramid's smoothing, which erodes it.
pub const COVERED_AT: f32 = 0.999;

/// Keep in sync with `PyramidParams` in shaders/sampling/pyramid.wgsl.
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
