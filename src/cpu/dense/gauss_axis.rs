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

/// [`gauss_axis`] for `M` components per voxel, a row of voxels at a time: each tap adds its
/// weight times the row it reads (along x the row shifted, clamped at the faces) to the output
/// row, the taps in order, so each value is the shader's sum, term by term.
fn smooth<const M: usize>(params: &GaussParams, input: &[f32], out: &mut [f32]) {
    let d = [params.nx as usize, params.ny as usize, params.nz as usize];
    let axis = params.axis as usize;
    let (n, r) = (d[axis] as isize, params.radius as isize);
    let taps: Vec<f32> = (-r..=r)
        .map(|t| params.tap(t.unsigned_abs() as u32))
        .collect();
    let row = M * d[0];
    let row_at = |j: usize, k: usize| &input[row * (j + d[1] * k)..][..row];
    out.par_chunks_mut(row * d[1])
        .enumerate()
        .for_each(|(k, out)| {
            for (j, out) in out.chunks_exact_mut(row).enumerate() {
                out.fill(0.0);
                for (t, &w) in (-r..=r).zip(&taps) {
                    // The tap's row along the axis, clamped to the grid.
                    let q = |c: usize| (c as isize + t).clamp(0, n - 1) as usize;
                    match axis {
                        0 => add_shifted::<M>(out, row_at(j, k), t, w),
                        1 => add_scaled(out, row_at(q(j), k), w),
                        _ => add_scaled(out, row_at(j, q(k)), w),
                    }
                }
            }
        });
}

/// out += w · row, element by element.
fn add_scaled(out: &mut [f32], row: &[f32], w: f32) {
    for (o, &x) in out.iter_mut().zip(row) {
        *o += w * x;
    }
}

/// out[i] += w · row[i + t] for each voxel i of a row of `M` components per voxel, the index
/// clamped to the row.
fn add_shifted<const M: usize>(out: &mut [f32], row: &[f32], t: isize, w: f32) {
    let nx = (out.len() / M) as isize;
    // Voxels whose tap lies inside the row: one shifted slice.
    let (lo, hi) = ((-t).clamp(0, nx), (nx - t).clamp(0, nx));
    if lo < hi {
        let (lo, hi) = (lo as usize, hi as usize);
        let from = (lo as isize + t) as usize;
        add_scaled(
            &mut out[M * lo..M * hi],
            &row[M * from..M * (from + hi - lo)],
            w,
        );
    }
    // The rest read the face's voxel.
    for i in (0..lo.min(nx)).chain(hi.max(lo)..nx) {
        let q = (i + t).clamp(0, nx - 1) as usize;
        let i = i as usize;
        for m in 0..M {
            out[M * i + m] += w * row[M * q + m];
        }
    }
}
