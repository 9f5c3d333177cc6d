//! CPU twin of shaders/sampling/pyramid.wgsl.

use crate::abi::PyramidParams;
use crate::cpu::common::voxel_index;
use rayon::prelude::*;

fn tap(o: u32, t: u32, factor: u32, n: u32) -> (f32, f32) {
    if factor == 1 {
        return (o as f32, if t == 0 { 1.0 } else { 0.0 });
    }
    let i = ((2 * o + t) as i32 - 1).clamp(0, n as i32 - 1);
    let w = if t == 1 || t == 2 { 3.0 } else { 1.0 } / 8.0;
    (i as f32, w)
}

/// Fills `output` (the coarser level) from the finer level `input`.
pub fn pyramid(params: &PyramidParams, input: &[f32], output: &mut [f32]) {
    let [nx, ny, _, _] = params.dims;
    output
        .par_chunks_mut((nx * ny) as usize)
        .enumerate()
        .for_each(|(k, out)| pyramid_slice(params, input, k as u32, out));
}

/// Output z-slice k of [`pyramid`]; also compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn pyramid_slice(params: &PyramidParams, input: &[f32], k: u32, out: &mut [f32]) {
    let [nx, ny, _, _] = params.dims;
    let n = [
        params.input_dims[0],
        params.input_dims[1],
        params.input_dims[2],
    ];
    let f = params.factors;
    for j in 0..ny {
        for i in 0..nx {
            let mut sum = 0.0f32;
            for tz in 0..4 {
                let z = tap(k, tz, f[2], n[2]);
                for ty in 0..4 {
                    let y = tap(j, ty, f[1], n[1]);
                    for tx in 0..4 {
                        let x = tap(i, tx, f[0], n[0]);
                        let w = x.1 * y.1 * z.1;
                        if w > 0.0 {
                            sum += w * input
                                [voxel_index(x.0 as u32, y.0 as u32, z.0 as u32, n) as usize];
                        }
                    }
                }
            }
            out[(i + nx * j) as usize] = sum;
        }
    }
}
