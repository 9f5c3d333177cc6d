//! CPU twin of shaders/nonrigid/lattice_splat.wgsl.

use crate::abi::SplatParams;
use crate::cpu::common::voxel_index;
use rayon::prelude::*;

fn reach_lo(a: u32, s: u32) -> u32 {
    if a > 0 {
        (a - 1) * s + 1
    } else {
        0
    }
}

fn weight(v: u32, a: u32, s: u32) -> f32 {
    (1.0 - (v as f32 / s as f32 - a as f32).abs()).max(0.0)
}

/// Fills `out` (3 floats per lattice node) with Σ_x w_n(x) values(x).
pub fn lattice_splat(params: &SplatParams, values: &[f32], out: &mut [f32]) {
    let [lx, ly, _, _] = params.dims;
    let sx = params.step[0];
    let n = [
        params.volume_dims[0],
        params.volume_dims[1],
        params.volume_dims[2],
    ];
    // The x weights of each node column's reach, the same for each of its rows.
    let x_reach: Vec<(std::ops::Range<u32>, Vec<f32>)> = (0..lx)
        .map(|a| {
            let xs = reach_lo(a, sx)..((a + 1) * sx).min(n[0]);
            let wxs = xs.clone().map(|i| weight(i, a, sx)).collect();
            (xs, wxs)
        })
        .collect();
    out.par_chunks_mut((3 * lx * ly) as usize)
        .enumerate()
        .for_each(|(c, slice)| splat_slice(params, &x_reach, values, c as u32, slice));
}

/// Node z-slice c of [`lattice_splat`]'s sums, from the x weights `x_reach` of each node
/// column's reach; also compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn splat_slice(
    params: &SplatParams,
    x_reach: &[(std::ops::Range<u32>, Vec<f32>)],
    values: &[f32],
    c: u32,
    slice: &mut [f32],
) {
    let lx = params.dims[0];
    let [_, sy, sz, _] = params.step;
    let n = [
        params.volume_dims[0],
        params.volume_dims[1],
        params.volume_dims[2],
    ];
    for (b, sums) in slice.chunks_exact_mut((3 * lx) as usize).enumerate() {
        let b = b as u32;
        sums.fill(0.0);
        // Each node's sum runs over its reach's voxels in the shader's order (z, then y, then
        // x), but a row of nodes is summed together, a voxel row at a time: one node's sum is
        // a chain of dependent additions, and taking the row's nodes in turn gives the
        // processor independent chains to overlap.
        for k in reach_lo(c, sz)..((c + 1) * sz).min(n[2]) {
            let wz = weight(k, c, sz);
            for j in reach_lo(b, sy)..((b + 1) * sy).min(n[1]) {
                let wy = weight(j, b, sy);
                let row = 3 * voxel_index(0, j, k, n) as usize;
                for ((xs, wxs), sum) in x_reach.iter().zip(sums.chunks_exact_mut(3)) {
                    let mut s = [sum[0], sum[1], sum[2]];
                    for (i, wx) in xs.clone().zip(wxs) {
                        let w = wx * wy * wz;
                        if w > 0.0 {
                            let v = row + 3 * i as usize;
                            for q in 0..3 {
                                s[q] += w * values[v + q];
                            }
                        }
                    }
                    sum.copy_from_slice(&s);
                }
            }
        }
    }
}
