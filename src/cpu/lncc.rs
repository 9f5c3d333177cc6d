//! CPU twins of shaders/local_moments.wgsl, shaders/lncc.wgsl, shaders/lncc_terms.wgsl and
//! shaders/lncc_gradient.wgsl (with shaders/window.wgsl).

use super::common::{dims3, is_covered, voxel_index};
use super::warp_image::{LatticeTaps, RowSamples};
use crate::abi::{LnccParams, LnccTermsParams, LocalMomentsParams, RbfGradParams, LOCAL_MOMENTS};
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

/// The statistics of one window (Window in shaders/window.wgsl).
pub(crate) struct Window {
    n: f32,
    pub(crate) ma: f32,
    pub(crate) mb: f32,
    pub(crate) va: f32,
    pub(crate) vb: f32,
    pub(crate) cab: f32,
    pub(crate) flat: bool,
}

/// The window of voxel v (index i, j, k) on a grid `d` (nx, ny, nz, radius) from its box
/// sums (window_at in shaders/window.wgsl).
pub(crate) fn window_at(sums: &[f32], v: usize, d: [u32; 4], [i, j, k]: [u32; 3]) -> Window {
    let n = (window_length(i, d[0], d[3])
        * window_length(j, d[1], d[3])
        * window_length(k, d[2], d[3])) as f32;
    let s = &sums[LOCAL_MOMENTS * v..LOCAL_MOMENTS * (v + 1)];
    let (ma, mb) = (s[0] / n, s[1] / n);
    let (saa, sbb) = (s[2] / n, s[3] / n);
    let va = saa - ma * ma;
    let vb = sbb - mb * mb;
    let cab = s[4] / n - ma * mb;
    let flat = va <= 1e-6 * saa || vb <= 1e-6 * sbb;
    Window {
        n,
        ma,
        mb,
        va,
        vb,
        cab,
        flat,
    }
}

/// ρ² at voxel v (index i, j, k), or −1 where a window is flat.
fn squared_correlation(params: &LnccParams, sums: &[f32], v: usize, ijk: [u32; 3]) -> f32 {
    let w = window_at(sums, v, params.dims, ijk);
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
    let d = params.dims;
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
                let kc = params.scale[0] * if is_covered(covered[v]) { 1.0 } else { 0.0 };
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
