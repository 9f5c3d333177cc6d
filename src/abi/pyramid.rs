//! Pyramid levels.

use super::*;

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
