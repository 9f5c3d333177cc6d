//! CPU twin of shaders/dense/gauss_axis.wgsl.

use crate::abi::dense::GaussParams;
use rayon::prelude::*;

/// Fills `out` with one axis's pass of the Gaussian smoothing of `input` (`params.components`
/// floats per voxel), a tap past a face reading the face's voxel. Each component's sum runs
/// over the offsets −radius ..= radius in order, as the shader's does; the taps' voxels are
/// found once for all components.
pub fn gauss_axis(params: &GaussParams, input: &[f32], out: &mut [f32]) {
    match params.components {
        1 => smooth::<1>(params, input, out),
        3 => smooth::<3>(params, input, out),
        m => panic!("gauss_axis smooths 1 or 3 components, not {m}"),
    }
}

/// [`gauss_axis`] for `M` components per voxel.
fn smooth<const M: usize>(params: &GaussParams, input: &[f32], out: &mut [f32]) {
    let d = [params.nx as usize, params.ny as usize, params.nz as usize];
    let axis = params.axis as usize;
    let stride = [1, d[0], d[0] * d[1]][axis];
    let (n, r) = (d[axis] as isize, params.radius as isize);
    let taps: Vec<f32> = (-r..=r)
        .map(|t| params.tap(t.unsigned_abs() as u32))
        .collect();
    out.par_chunks_mut(M * d[0] * d[1])
        .enumerate()
        .for_each(|(k, out)| {
            for j in 0..d[1] {
                for i in 0..d[0] {
                    let v = i + d[0] * (j + d[1] * k);
                    let c = [i, j, k][axis] as isize;
                    let mut sums = [0.0f32; M];
                    for (t, w) in (-r..=r).zip(&taps) {
                        // The tap's voxel along the axis, clamped to the grid.
                        let q = (c + t).clamp(0, n - 1);
                        let at = M * (v as isize + (q - c) * stride as isize) as usize;
                        for (m, sum) in sums.iter_mut().enumerate() {
                            *sum += w * input[at + m];
                        }
                    }
                    let o = M * (i + d[0] * j);
                    out[o..o + M].copy_from_slice(&sums);
                }
            }
        });
}
