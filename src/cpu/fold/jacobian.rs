//! CPU twin of shaders/fold/jacobian.wgsl, a row of voxels at a time: the row's differences
//! along each axis are taken over its three floats per voxel at once, then each voxel's rows
//! of I + du/dx and their determinant. Each voxel's operations are the shader's, in its order,
//! so the values are the same bits.

use crate::abi::JacobianParams;
use crate::cpu::common::difference;
use rayon::prelude::*;

/// A row's differences along x, y and z, 3 floats per voxel like the field.
#[derive(Default)]
struct Differences([Vec<f32>; 3]);

/// Fills `det` (one value per voxel) with det(I + du/dx).
pub fn jacobian(params: &JacobianParams, field: &[f32], det: &mut [f32]) {
    let [nx, ny, _, _] = params.dims.map(|n| n as usize);
    det.par_chunks_mut(nx * ny).enumerate().for_each_init(
        Differences::default,
        |differences, (k, slice)| {
            for (j, out) in slice.chunks_exact_mut(nx).enumerate() {
                jacobian_row(params, field, [j, k], differences, out);
            }
        },
    );
}

/// Row (j, k) of [`jacobian`] into `out`; also compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn jacobian_row(
    params: &JacobianParams,
    field: &[f32],
    [j, k]: [usize; 2],
    differences: &mut Differences,
    out: &mut [f32],
) {
    differences.take(params, field, [j, k]);
    determinants(params.mm_to_index, differences, out);
}

impl Differences {
    /// Row (j, k)'s differences along each axis: central, one-sided at the faces, 0 along an
    /// axis one voxel long (the shader's `difference`).
    #[inline(always)]
    fn take(&mut self, params: &JacobianParams, field: &[f32], [j, k]: [usize; 2]) {
        let [nx, ny, nz, _] = params.dims.map(|n| n as usize);
        let row = |j: usize, k: usize| &field[3 * nx * (j + ny * k)..][..3 * nx];
        let [dx, dy, dz] = &mut self.0;
        for lanes in [&mut *dx, &mut *dy, &mut *dz] {
            lanes.resize(3 * nx, 0.0);
        }
        // Along x the neighbours are the voxels beside, 3 floats away.
        let here = row(j, k);
        for (i, d) in dx.chunks_exact_mut(3).enumerate() {
            let (lo, hi) = (3 * (i.max(1) - 1), 3 * (i + 1).min(nx - 1));
            for c in 0..3 {
                d[c] = difference(here[lo + c], here[hi + c], i as u32, nx as u32);
            }
        }
        let beside = [
            (row(j.max(1) - 1, k), row((j + 1).min(ny - 1), k), [j, ny]),
            (row(j, k.max(1) - 1), row(j, (k + 1).min(nz - 1)), [k, nz]),
        ];
        for (d, (lo, hi, [c, n])) in [dy, dz].into_iter().zip(beside) {
            for ((d, &hi), &lo) in d.iter_mut().zip(hi).zip(lo) {
                *d = difference(lo, hi, c as u32, n as u32);
            }
        }
    }
}

/// det(I + du/dx) of each voxel of a row from its `differences` (du/d(index)), with
/// d(index)/dx the rows `m`.
#[inline(always)]
fn determinants(m: [[f32; 4]; 3], differences: &Differences, out: &mut [f32]) {
    let [dx, dy, dz] = &differences.0;
    let voxels = dx
        .chunks_exact(3)
        .zip(dy.chunks_exact(3))
        .zip(dz.chunks_exact(3));
    for (det, ((a, b), c)) in out.iter_mut().zip(voxels) {
        // Row r of du/dx: component r's index derivatives times d(index)/dx, plus row r of I.
        let entry = |r: usize, s: usize| {
            let identity = if r == s { 1.0 } else { 0.0 };
            a[r] * m[0][s] + b[r] * m[1][s] + c[r] * m[2][s] + identity
        };
        let (r0x, r0y, r0z) = (entry(0, 0), entry(0, 1), entry(0, 2));
        let (r1x, r1y, r1z) = (entry(1, 0), entry(1, 1), entry(1, 2));
        let (r2x, r2y, r2z) = (entry(2, 0), entry(2, 1), entry(2, 2));
        // common::det3's order.
        *det = r0x * (r1y * r2z - r1z * r2y) - r0y * (r1x * r2z - r1z * r2x)
            + r0z * (r1x * r2y - r1y * r2x);
    }
}
