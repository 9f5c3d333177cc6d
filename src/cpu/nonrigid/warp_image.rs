//! CPU twin of shaders/nonrigid/warp_image.wgsl.

use crate::abi::RbfGradParams;
use crate::cpu::lattice_warp::{LatticeTaps, RowSamples};
use rayon::prelude::*;

/// Fills `warped` (one per voxel) with `moving` seen through the warp `lattice`.
pub fn warp_image(params: &RbfGradParams, lattice: &[f32], moving: &[f32], warped: &mut [f32]) {
    let [nx, ny, _, _] = params.dims;
    let taps = LatticeTaps::new(params);
    warped
        .par_chunks_mut((nx * ny) as usize)
        .enumerate()
        .for_each_init(RowSamples::default, |samples, (k, slice)| {
            for (j, out) in slice.chunks_exact_mut(nx as usize).enumerate() {
                let (j, k) = (j as u32, k as u32);
                samples.sample(params, &taps, lattice, moving, [j, k]);
                out.copy_from_slice(&samples.sample[0]);
            }
        });
}
