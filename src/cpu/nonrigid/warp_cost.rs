//! CPU twin of shaders/nonrigid/warp_cost.wgsl.

use crate::abi::RbfGradParams;
use crate::backend::CostImages;
use crate::cpu::common::{is_covered, voxel_index};
use crate::cpu::lattice_warp::{LatticeTaps, RowSamples};
use rayon::prelude::*;

/// Fills `gradient` (3 floats per voxel: c · 2 (W − T) ∇I0, world mm) and `rows` (Σ c (W − T)²
/// per row of x, index j + ny k).
pub fn warp_cost(
    params: &RbfGradParams,
    lattice: &[f32],
    images: &CostImages<[f32]>,
    gradient: &mut [f32],
    rows: &mut [f32],
) {
    let [nx, ny, nz, _] = params.dims;
    let d = [nx, ny, nz];
    let taps = LatticeTaps::new(params);
    gradient
        .par_chunks_mut(3 * nx as usize)
        .zip(rows.par_iter_mut())
        .enumerate()
        .for_each_init(RowSamples::default, |samples, (row, (out, sum_out))| {
            let (j, k) = (row as u32 % ny, row as u32 / ny);
            samples.sample(params, &taps, lattice, images.moving, [j, k]);
            let first = voxel_index(0, j, k, d) as usize;
            let voxels = first..first + nx as usize;
            *sum_out = row_cost(
                samples,
                &images.fixed[voxels.clone()],
                &images.covered[voxels],
                out,
            );
        });
}

/// One row's masked squared residuals, summed, and its gradient terms into `out` (3 floats
/// per voxel), from the row's `samples` of the moving image and its `fixed` and `covered`
/// values. Also compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn row_cost(samples: &RowSamples, fixed: &[f32], covered: &[f32], out: &mut [f32]) -> f32 {
    let [w, g @ ..] = &samples.sample;
    let mut sum = 0.0f32;
    for i in 0..fixed.len() {
        let t = fixed[i];
        let c = if is_covered(covered[i]) { 1.0 } else { 0.0 };
        let e = w[i] - t;
        // warped_sample in shaders/warp_sample.wgsl: ∂(W − t)²/∂R, zero outside.
        let residual = 2.0 * e;
        sum += c * e * e;
        for a in 0..3 {
            let s = if samples.inside[i] {
                residual * g[a][i]
            } else {
                0.0
            };
            out[3 * i + a] = c * s;
        }
    }
    sum
}
