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

/// [`gauss_axis`] for `M` components per voxel, a row of voxels at a time: each output value is
/// the sum of the taps' weights times the values they read (along x the row shifted, clamped
/// at the faces; along y and z the rows beside, clamped to the grid), the taps in order, so
/// each value is the shader's sum, term by term.
fn smooth<const M: usize>(params: &GaussParams, input: &[f32], out: &mut [f32]) {
    let d = [params.nx as usize, params.ny as usize, params.nz as usize];
    let axis = params.axis as usize;
    let (n, r) = (d[axis] as isize, params.radius as isize);
    let weights: Vec<f32> = (-r..=r)
        .map(|t| params.tap(t.unsigned_abs() as u32))
        .collect();
    let row = M * d[0];
    let row_at = |j: usize, k: usize| &input[row * (j + d[1] * k)..][..row];
    out.par_chunks_mut(row * d[1])
        .enumerate()
        .for_each_init(Vec::new, |taps, (k, out)| {
            for (j, out) in out.chunks_exact_mut(row).enumerate() {
                if axis == 0 {
                    along_row::<M>(out, row_at(j, k), &weights);
                    continue;
                }
                // The tap's row along the axis, clamped to the grid.
                let q = |c: usize, t: isize| (c as isize + t).clamp(0, n - 1) as usize;
                taps.clear();
                taps.extend((-r..=r).zip(&weights).map(|(t, &w)| match axis {
                    1 => (w, row_at(q(j, t), k)),
                    _ => (w, row_at(j, q(k, t))),
                }));
                weighted_sum(out, taps);
            }
        });
}

/// Values summed side by side: sixteen, two AVX2 registers' f32 lanes.
const BLOCK: usize = 16;

/// out[e] = Σ w · row[e] over `taps` (each a weight and a row as long as `out`), the taps in
/// order, [`BLOCK`] values at a time held while every tap adds to them. Also compiled for AVX2
/// (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn weighted_sum(out: &mut [f32], taps: &[(f32, &[f32])]) {
    let done = out.len() - out.len() % BLOCK;
    for (b, out) in out[..done].chunks_exact_mut(BLOCK).enumerate() {
        let mut sums = [0.0f32; BLOCK];
        for &(w, row) in taps {
            let row = &row[b * BLOCK..][..BLOCK];
            for (s, &x) in sums.iter_mut().zip(row) {
                *s += w * x;
            }
        }
        out.copy_from_slice(&sums);
    }
    for (e, out) in out.iter_mut().enumerate().skip(done) {
        *out = taps.iter().fold(0.0, |s, &(w, row)| s + w * row[e]);
    }
}

/// One row's pass along x (`M` components per voxel): out = Σ w · row shifted by each tap, the
/// taps in order, each added to the whole row at once (held in the first level cache, this
/// ran as fast as summing blocks of voxels tap by tap as [`weighted_sum`] does).
fn along_row<const M: usize>(out: &mut [f32], row: &[f32], weights: &[f32]) {
    let r = (weights.len() / 2) as isize;
    out.fill(0.0);
    for (t, &w) in (-r..=r).zip(weights) {
        add_shifted::<M>(out, row, t, w);
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Affine, Grid};

    /// gauss_axis.wgsl read voxel by voxel: each component's sum over the taps in order, a tap
    /// past a face reading the face's voxel.
    fn shader(params: &GaussParams, input: &[f32]) -> Vec<f32> {
        let d = [params.nx as usize, params.ny as usize, params.nz as usize];
        let (axis, m, r) = (
            params.axis as usize,
            params.components as usize,
            params.radius as isize,
        );
        let mut out = vec![0.0; input.len()];
        for v in 0..d[0] * d[1] * d[2] {
            let p = [v % d[0], v / d[0] % d[1], v / (d[0] * d[1])];
            for c in 0..m {
                let mut sum = 0.0f32;
                for t in -r..=r {
                    let mut q = p;
                    q[axis] = (p[axis] as isize + t).clamp(0, d[axis] as isize - 1) as usize;
                    let at = q[0] + d[0] * (q[1] + d[1] * q[2]);
                    sum += params.tap(t.unsigned_abs() as u32) * input[m * at + c];
                }
                out[m * v + c] = sum;
            }
        }
        out
    }

    #[test]
    fn every_pass_gives_the_shaders_sums_to_the_bit() {
        // Rows both shorter than the window (3 voxels) and longer than a block of sums.
        for dims in [[37usize, 6, 19], [3, 21, 2]] {
            let grid = Grid::new(dims, Affine::identity()).unwrap();
            for (components, sigma) in [(1, 0.75), (3, 2.14)] {
                let input: Vec<f32> = (0..components * grid.len())
                    .map(|i| ((i as f32) * 0.37).sin() * 2.0)
                    .collect();
                for params in GaussParams::passes(&grid, components, sigma) {
                    let mut out = vec![0.0; input.len()];
                    gauss_axis(&params, &input, &mut out);
                    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(
                        bits(&out),
                        bits(&shader(&params, &input)),
                        "{dims:?} axis {}",
                        params.axis
                    );
                }
            }
        }
    }
}
