//! CPU twin of shaders/correlation/local_moments.wgsl.

use crate::abi::{LocalMomentsParams, LOCAL_MOMENTS};
use crate::cpu::common::{dims3, voxel_index};
use rayon::prelude::*;

/// Fills `out` (5 floats per voxel) with one axis's pass of the box sums: from the images
/// `input` (a) and `other` (b) on the first pass, else from the stack in `input`.
pub fn local_moments(params: &LocalMomentsParams, input: &[f32], other: &[f32], out: &mut [f32]) {
    let d = dims3(params.dims);
    let (axis, r) = (params.axis as usize, params.radius);
    let moments_at = |v: usize| -> [f32; LOCAL_MOMENTS] {
        if params.first == 1 {
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
