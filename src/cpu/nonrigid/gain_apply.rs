//! CPU twin of shaders/nonrigid/gain_apply.wgsl.

use crate::abi::GainParams;
use crate::cpu::common::{affine_row, voxel_index};
use crate::sample::trilinear;
use rayon::prelude::*;

/// Fills `gained` with `moving` times the gain interpolated from the smoothed grid.
pub fn gain_apply(params: &GainParams, gain: &[f32], moving: &[f32], gained: &mut [f32]) {
    let [nx, ny, nz, _] = params.dims;
    let coarse = [
        params.coarse_dims[0],
        params.coarse_dims[1],
        params.coarse_dims[2],
    ];
    debug_assert_eq!(gained.len(), (nx * ny * nz) as usize);
    gained
        .par_chunks_mut((nx * ny) as usize)
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..ny {
                for i in 0..nx {
                    let p = [i as f32, j as f32, k as f32];
                    let q: [f32; 3] = std::array::from_fn(|a| {
                        affine_row(params.to_coarse[a], p).clamp(0.0, coarse[a] as f32 - 1.0)
                    });
                    let v = voxel_index(i, j, k as u32, [nx, ny, nz]) as usize;
                    slice[(i + nx * j) as usize] = moving[v] * trilinear(gain, q, coarse, 1.0);
                }
            }
        });
}
