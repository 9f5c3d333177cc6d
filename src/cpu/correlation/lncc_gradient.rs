//! CPU twin of shaders/correlation/lncc_gradient.wgsl (with shaders/lattice_warp.wgsl and
//! shaders/warp_sample.wgsl).

use crate::abi::{RbfGradParams, LOCAL_MOMENTS};
use crate::cpu::common::voxel_index;
use crate::cpu::lattice_warp::{LatticeTaps, RowSamples};
use rayon::prelude::*;

/// Fills `gradient` (3 floats per voxel: ∂cost/∂W · ∇I0, world mm) from the box-summed terms
/// `summed` (A1..A4 per voxel), with ∂cost/∂W = −2 (T A1 − A2 − W A3 + A4), of `moving` seen
/// through the warp `lattice` against `fixed`.
pub fn lncc_gradient(
    params: &RbfGradParams,
    lattice: &[f32],
    [moving, fixed]: [&[f32]; 2],
    summed: &[f32],
    gradient: &mut [f32],
) {
    let [nx, ny, nz, _] = params.dims;
    let d = [nx, ny, nz];
    let taps = LatticeTaps::new(params);
    gradient
        .par_chunks_mut(3 * nx as usize)
        .enumerate()
        .for_each_init(RowSamples::default, |samples, (row, out)| {
            let (j, k) = (row as u32 % ny, row as u32 / ny);
            samples.sample(params, &taps, lattice, moving, [j, k]);
            let s = &samples.sample;
            for i in 0..nx {
                let v = voxel_index(i, j, k, d) as usize;
                let t = fixed[v];
                let a = &summed[LOCAL_MOMENTS * v..LOCAL_MOMENTS * (v + 1)];
                let i = i as usize;
                let slope = -2.0 * (t * a[0] - a[1] - s[0][i] * a[2] + a[3]);
                for axis in 0..3 {
                    out[3 * i + axis] = slope * s[1 + axis][i];
                }
            }
        });
}
