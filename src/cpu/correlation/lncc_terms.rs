//! CPU twin of shaders/correlation/lncc_terms.wgsl (with shaders/window.wgsl).

use crate::abi::{LnccTermsParams, LOCAL_MOMENTS};
use crate::cpu::common::{dims3, is_covered, voxel_index};
use crate::cpu::window::window_at;
use rayon::prelude::*;

/// Fills `terms` (5 floats per voxel: K c α / n, K c α mb / n, K c β / n, K c β ma / n, 0) and
/// `rows` (K Σ c (1 − ρ²) per row of x, index j + ny k) from the box sums `sums` and the
/// coverage `covered`.
pub fn lncc_terms(
    params: &LnccTermsParams,
    sums: &[f32],
    covered: &[f32],
    terms: &mut [f32],
    rows: &mut [f32],
) {
    let d = [
        params.dims[0],
        params.dims[1],
        params.dims[2],
        params.radius,
    ];
    let [nx, ny, _] = dims3(d);
    terms
        .par_chunks_mut(LOCAL_MOMENTS * nx as usize)
        .zip(rows.par_iter_mut())
        .enumerate()
        .for_each(|(row, (out, sum_out))| {
            let (j, k) = (row as u32 % ny, row as u32 / ny);
            let mut sum = 0.0f32;
            for i in 0..nx {
                let v = voxel_index(i, j, k, dims3(d)) as usize;
                let w = window_at(sums, v, d, [i, j, k]);
                let kc = params.scale * if is_covered(covered[v]) { 1.0 } else { 0.0 };
                let (mut rho2, mut alpha, mut beta) = (0.0f32, 0.0f32, 0.0f32);
                if !w.flat {
                    alpha = w.cab / (w.va * w.vb);
                    beta = alpha * w.cab / w.va;
                    rho2 = (alpha * w.cab).min(1.0);
                }
                sum += kc * (1.0 - rho2);
                let (a, b) = (kc * alpha / w.n, kc * beta / w.n);
                let o = LOCAL_MOMENTS * i as usize;
                out[o..o + LOCAL_MOMENTS].copy_from_slice(&[a, a * w.mb, b, b * w.ma, 0.0]);
            }
            *sum_out = sum;
        });
}
