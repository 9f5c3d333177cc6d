//! CPU twin of shaders/correlation/lncc.wgsl (with shaders/window.wgsl).

use crate::abi::LnccParams;
use crate::cpu::common::dims3;
use crate::cpu::window::window_at;
use rayon::prelude::*;

/// ρ² at voxel v (index i, j, k), or −1 where a window is flat.
fn squared_correlation(params: &LnccParams, sums: &[f32], v: usize, ijk: [u32; 3]) -> f32 {
    let [nx, ny, nz, _] = params.dims;
    let w = window_at(sums, v, [nx, ny, nz, params.radius], ijk);
    if w.flat {
        return -1.0;
    }
    (w.cab * w.cab / (w.va * w.vb)).min(1.0)
}

/// Fills `out` (2 floats per chunk) with each chunk's Σ ρ² and the voxels counted.
pub fn lncc(params: &LnccParams, sums: &[f32], out: &mut [f32]) {
    let [voxels, per_chunk, _, _] = params.chunks.map(|n| n as usize);
    let [nx, ny, _] = dims3(params.dims);
    out.par_chunks_mut(2).enumerate().for_each(|(c, chunk)| {
        let (mut total, mut counted) = (0.0f32, 0.0f32);
        for v in c * per_chunk..((c + 1) * per_chunk).min(voxels) {
            let u = v as u32;
            let rho2 = squared_correlation(params, sums, v, [u % nx, (u / nx) % ny, u / (nx * ny)]);
            if rho2 >= 0.0 {
                total += rho2;
                counted += 1.0;
            }
        }
        chunk.copy_from_slice(&[total, counted]);
    });
}
