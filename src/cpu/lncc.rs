//! CPU twins of shaders/local_moments.wgsl and shaders/lncc.wgsl.

use super::common::{dims3, voxel_index};
use crate::abi::{LnccParams, LocalMomentsParams, LOCAL_MOMENTS};
use rayon::prelude::*;

/// Fills `out` (5 floats per voxel) with one axis's pass of the box sums: from the images
/// `input` (a) and `other` (b) on the first pass, else from the stack in `input`.
pub fn local_moments(params: &LocalMomentsParams, input: &[f32], other: &[f32], out: &mut [f32]) {
    let d = dims3(params.dims);
    let (axis, r) = (params.axis[0] as usize, params.dims[3]);
    let moments_at = |v: usize| -> [f32; LOCAL_MOMENTS] {
        if params.axis[1] == 1 {
            let (a, b) = (input[v], other[v]);
            return [a, b, a * a, b * b, a * b];
        }
        std::array::from_fn(|k| input[LOCAL_MOMENTS * v + k])
    };
    let slice_len = LOCAL_MOMENTS * (d[0] * d[1]) as usize;
    out.par_chunks_mut(slice_len)
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..d[1] {
                for i in 0..d[0] {
                    let mut p = [i, j, k as u32];
                    let c = p[axis];
                    let mut sums = [0.0f32; LOCAL_MOMENTS];
                    for a in c.max(r) - r..(c + r + 1).min(d[axis]) {
                        p[axis] = a;
                        let m = moments_at(voxel_index(p[0], p[1], p[2], d) as usize);
                        for (s, m) in sums.iter_mut().zip(m) {
                            *s += m;
                        }
                    }
                    let at = LOCAL_MOMENTS * (i + d[0] * j) as usize;
                    slice[at..at + LOCAL_MOMENTS].copy_from_slice(&sums);
                }
            }
        });
}

/// Voxels of the window along one axis at coordinate c of n, radius r.
fn window_length(c: u32, n: u32, r: u32) -> u32 {
    (c + r + 1).min(n) - (c.max(r) - r)
}

/// ρ² at voxel v (index i, j, k), or −1 where a window is flat.
fn squared_correlation(params: &LnccParams, sums: &[f32], v: usize, [i, j, k]: [u32; 3]) -> f32 {
    let d = params.dims;
    let n = (window_length(i, d[0], d[3])
        * window_length(j, d[1], d[3])
        * window_length(k, d[2], d[3])) as f32;
    let s = &sums[LOCAL_MOMENTS * v..LOCAL_MOMENTS * (v + 1)];
    let (ma, mb) = (s[0] / n, s[1] / n);
    let (saa, sbb) = (s[2] / n, s[3] / n);
    let va = saa - ma * ma;
    let vb = sbb - mb * mb;
    let cab = s[4] / n - ma * mb;
    if va <= 1e-6 * saa || vb <= 1e-6 * sbb {
        return -1.0;
    }
    (cab * cab / (va * vb)).min(1.0)
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
