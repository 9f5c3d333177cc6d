//! CPU twin of shaders/fold/jacobian.wgsl: one slice per rayon task.

use crate::abi::JacobianParams;
use crate::cpu::common::{det3, voxel_index};
use glam::Vec3;
use rayon::prelude::*;

fn displacement(params: &JacobianParams, field: &[f32], i: u32, j: u32, k: u32) -> Vec3 {
    let dims = [params.dims[0], params.dims[1], params.dims[2]];
    let n = 3 * voxel_index(i, j, k, dims) as usize;
    Vec3::new(field[n], field[n + 1], field[n + 2])
}

fn difference(lo: Vec3, hi: Vec3, c: u32, n: u32) -> Vec3 {
    if n == 1 {
        return Vec3::ZERO;
    }
    if c == 0 || c == n - 1 {
        return hi - lo;
    }
    (hi - lo) * 0.5
}

/// Fills `det` (one value per voxel) with det(I + du/dx).
pub fn jacobian(params: &JacobianParams, field: &[f32], det: &mut [f32]) {
    let [nx, ny, nz, _] = params.dims;
    let m = params.mm_to_index.map(|r| Vec3::new(r[0], r[1], r[2]));
    let u = |i, j, k| displacement(params, field, i, j, k);
    det.par_chunks_mut((nx * ny) as usize)
        .enumerate()
        .for_each(|(zl, out)| {
            let k = zl as u32;
            for j in 0..ny {
                for i in 0..nx {
                    let dx = difference(u(i.max(1) - 1, j, k), u((i + 1).min(nx - 1), j, k), i, nx);
                    let dy = difference(u(i, j.max(1) - 1, k), u(i, (j + 1).min(ny - 1), k), j, ny);
                    let dz = difference(u(i, j, k.max(1) - 1), u(i, j, (k + 1).min(nz - 1)), k, nz);
                    let r0 = dx.x * m[0] + dy.x * m[1] + dz.x * m[2] + Vec3::X;
                    let r1 = dx.y * m[0] + dy.y * m[1] + dz.y * m[2] + Vec3::Y;
                    let r2 = dx.z * m[0] + dy.z * m[1] + dz.z * m[2] + Vec3::Z;
                    out[voxel_index(i, j, 0, [nx, ny, 1]) as usize] = det3(r0, r1, r2);
                }
            }
        });
}
