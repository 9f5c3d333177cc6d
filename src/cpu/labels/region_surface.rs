//! CPU twin of shaders/labels/region_surface.wgsl.

use crate::abi::SurfaceParams;
use rayon::prelude::*;

/// Fills `surface` with each voxel's region number where a six-neighbour inside the grid has
/// another number, else 0.
pub fn region_surface(params: &SurfaceParams, regions: &[f32], surface: &mut [f32]) {
    let [nx, ny, nz, _] = params.dims.map(|c| c as usize);
    let stride = [1, nx, nx * ny];
    surface.par_iter_mut().enumerate().for_each(|(v, out)| {
        let index = [v % nx, v / nx % ny, v / (nx * ny)];
        let dims = [nx, ny, nz];
        let region = regions[v];
        let boundary = (0..3).any(|a| {
            (index[a] > 0 && regions[v - stride[a]] != region)
                || (index[a] + 1 < dims[a] && regions[v + stride[a]] != region)
        });
        *out = if boundary && region > 0.0 {
            region
        } else {
            0.0
        };
    });
}
