//! CPU twin of shaders/correlation/local_moments.wgsl.

use crate::abi::{LocalMomentsParams, LOCAL_MOMENTS};
use crate::cpu::common::dims3;
use rayon::prelude::*;

/// Fills `out` (5 floats per voxel) with one axis's pass of the box sums: from the images
/// `input` (a) and `other` (b) on the first pass, else from the stack in `input`.
pub fn local_moments(params: &LocalMomentsParams, input: &[f32], other: &[f32], out: &mut [f32]) {
    let d = dims3(params.dims);
    let row = LOCAL_MOMENTS * d[0] as usize;
    out.par_chunks_mut(row * d[1] as usize)
        .enumerate()
        .for_each_init(
            || vec![0.0; row],
            |moments, (k, slice)| {
                for (j, out) in slice.chunks_exact_mut(row).enumerate() {
                    sum_row(params, (input, other), [j, k], moments, out);
                }
            },
        );
}

/// Row (j, k) of the pass, a row of voxels at a time: each of the window's taps along the axis,
/// in order, adds the row of moments it reads (along x the row shifted, only where the tap lies
/// inside the grid) to the output row, so each voxel's sum is the shader's, term by term, and
/// the adds vectorise. Also compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn sum_row(
    params: &LocalMomentsParams,
    images: (&[f32], &[f32]),
    [j, k]: [usize; 2],
    moments: &mut [f32],
    out: &mut [f32],
) {
    let d = dims3(params.dims).map(|n| n as usize);
    let (axis, r) = (params.axis as usize, params.radius as usize);
    out.fill(0.0);
    if axis == 0 {
        let row = moments_row(params, images, [j, k], moments);
        for t in 0..=2 * r {
            add_shifted(out, row, t as isize - r as isize);
        }
        return;
    }
    let c = [0, j, k][axis];
    for a in c.max(r) - r..(c + r + 1).min(d[axis]) {
        let at = if axis == 1 { [a, k] } else { [j, a] };
        let row = moments_row(params, images, at, moments);
        for (o, &m) in out.iter_mut().zip(row) {
            *o += m;
        }
    }
}

/// The moments of row (j, k): (a, b, a², b², ab) per voxel from the two images on the first
/// pass (into `buffer`), else the stack's row itself.
#[inline(always)]
fn moments_row<'a>(
    params: &LocalMomentsParams,
    (input, other): (&'a [f32], &[f32]),
    [j, k]: [usize; 2],
    buffer: &'a mut [f32],
) -> &'a [f32] {
    let d = dims3(params.dims).map(|n| n as usize);
    let start = d[0] * (j + d[1] * k);
    if params.first != 1 {
        return &input[LOCAL_MOMENTS * start..][..LOCAL_MOMENTS * d[0]];
    }
    let (a, b) = (&input[start..][..d[0]], &other[start..][..d[0]]);
    for ((m, &a), &b) in buffer.chunks_exact_mut(LOCAL_MOMENTS).zip(a).zip(b) {
        m.copy_from_slice(&[a, b, a * a, b * b, a * b]);
    }
    buffer
}

/// out[i] += row[i + t] for each voxel i of the row whose tap i + t lies inside it (5 floats
/// per voxel).
#[inline(always)]
fn add_shifted(out: &mut [f32], row: &[f32], t: isize) {
    let n = (out.len() / LOCAL_MOMENTS) as isize;
    let (lo, hi) = ((-t).clamp(0, n), (n - t).clamp(0, n));
    if lo >= hi {
        return;
    }
    let (lo, hi, from) = (lo as usize, hi as usize, (lo + t) as usize);
    let out = &mut out[LOCAL_MOMENTS * lo..LOCAL_MOMENTS * hi];
    for (o, &m) in out.iter_mut().zip(&row[LOCAL_MOMENTS * from..]) {
        *o += m;
    }
}
