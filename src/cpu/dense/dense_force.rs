//! CPU twin of shaders/dense/dense_force.wgsl (with shaders/window.wgsl).

use crate::abi::dense::{ForceParams, ForceTerm, VOLUME_DET_FLOOR};
use crate::backend::dense::ForceImages;
use crate::cpu::common::{is_covered, voxel_index};
use crate::cpu::window::window_at;
use glam::Vec3;
use rayon::prelude::*;

/// Central difference of W along one axis at coordinate c of n (one-sided at the ends).
fn slope(lo: f32, hi: f32, c: u32, n: u32) -> f32 {
    if n == 1 {
        return 0.0;
    }
    if c == 0 || c == n - 1 {
        return hi - lo;
    }
    (hi - lo) * 0.5
}

/// A row of d(index)/d(world) as a vector.
fn row(r: [f32; 4]) -> Vec3 {
    Vec3::new(r[0], r[1], r[2])
}

/// ∇W at voxel (i, j, k), world mm.
fn gradient(params: &ForceParams, moving: &[f32], [i, j, k]: [u32; 3], d: [u32; 3]) -> Vec3 {
    let w = |i, j, k| moving[voxel_index(i, j, k, d) as usize];
    let gx = slope(
        w(i.max(1) - 1, j, k),
        w((i + 1).min(d[0] - 1), j, k),
        i,
        d[0],
    );
    let gy = slope(
        w(i, j.max(1) - 1, k),
        w(i, (j + 1).min(d[1] - 1), k),
        j,
        d[1],
    );
    let gz = slope(
        w(i, j, k.max(1) - 1),
        w(i, j, (k + 1).min(d[2] - 1)),
        k,
        d[2],
    );
    let m = &params.mm_to_index;
    gx * row(m[0]) + gy * row(m[1]) + gz * row(m[2])
}

/// The force's factor along ∇W and the cost at voxel v (index `ijk`).
fn along_and_cost(
    params: &ForceParams,
    images: &ForceImages<[f32]>,
    v: usize,
    ijk: [u32; 3],
) -> (f32, f32) {
    let c = if is_covered(images.covered[v]) {
        1.0
    } else {
        0.0
    };
    let (w, f) = (images.moving[v], images.fixed[v]);
    if params.term == ForceTerm::Volume as u32 {
        let det = w.max(VOLUME_DET_FLOOR);
        let l = det.ln();
        return (c * 2.0 * (1.0 - l) / det, c * l * l);
    }
    if params.term != ForceTerm::Lncc as u32 {
        return (c * (f - w), c * (w - f) * (w - f));
    }
    // local_moments summed a = W and b = F.
    let win = window_at(images.sums, v, params.window_dims(), ijk);
    if win.flat {
        return (0.0, 1.0);
    }
    let spread = win.va * win.vb;
    let along = c * (2.0 * win.cab / spread) * ((f - win.mb) - win.cab / win.va * (w - win.ma));
    (along, 1.0 - c * (win.cab * win.cab / spread))
}

/// Fills `force` (3 floats per voxel) and `cost` (1 float per voxel).
pub fn dense_force(
    params: &ForceParams,
    images: &ForceImages<[f32]>,
    force: &mut [f32],
    cost: &mut [f32],
) {
    let d = [params.nx, params.ny, params.nz];
    let slice = (d[0] * d[1]) as usize;
    force
        .par_chunks_mut(3 * slice)
        .zip(cost.par_chunks_mut(slice))
        .enumerate()
        .for_each(|(k, (force, cost))| {
            for j in 0..d[1] {
                for i in 0..d[0] {
                    let ijk = [i, j, k as u32];
                    let at = (i + d[0] * j) as usize;
                    let v = at + k * slice;
                    let (along, term) = along_and_cost(params, images, v, ijk);
                    let g = gradient(params, images.moving, ijk, d);
                    force[3 * at..3 * at + 3].copy_from_slice(&[
                        along * g.x,
                        along * g.y,
                        along * g.z,
                    ]);
                    cost[at] = term;
                }
            }
        });
}
