//! CPU twin of shaders/dense/dense_force.wgsl (with shaders/window.wgsl).

use crate::abi::dense::{ForceParams, ForceTerm, VOLUME_DET_FLOOR};
use crate::backend::dense::ForceImages;
use crate::cpu::common::{difference, is_covered, voxel_index};
use crate::cpu::window::window_at;
use glam::Vec3;
use rayon::prelude::*;

/// The force's factor along ∇W and the cost at voxel v (index `ijk`).
#[inline(always)]
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
    let [nx, ny] = [params.nx as usize, params.ny as usize];
    force
        .par_chunks_mut(3 * nx * ny)
        .zip(cost.par_chunks_mut(nx * ny))
        .enumerate()
        .for_each_init(RowLanes::default, |lanes, (k, (force, cost))| {
            let rows = force
                .chunks_exact_mut(3 * nx)
                .zip(cost.chunks_exact_mut(nx));
            for (j, (force, cost)) in rows.enumerate() {
                force_row(lanes, params, images, [j as u32, k as u32], (force, cost));
            }
        });
}

/// Per voxel of one row: the force's factor along ∇W, then ∇W's index-space components.
#[derive(Default)]
struct RowLanes {
    along: Vec<f32>,
    slopes: [Vec<f32>; 3],
}

/// Row (j, k) of the shader, in passes over the row's voxels (the factor and the cost, the
/// slopes along each axis, the force) so that the passes vectorise where they can; each voxel's
/// operations are the shader's, in its order, so the values are the same bits. Also compiled
/// for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn force_row(
    lanes: &mut RowLanes,
    params: &ForceParams,
    images: &ForceImages<[f32]>,
    [j, k]: [u32; 2],
    (force, cost): (&mut [f32], &mut [f32]),
) {
    let d = [params.nx, params.ny, params.nz];
    let nx = d[0] as usize;
    lanes.along.resize(nx, 0.0);
    let start = voxel_index(0, j, k, d) as usize;
    for (i, (along, cost)) in lanes.along.iter_mut().zip(cost.iter_mut()).enumerate() {
        (*along, *cost) = along_and_cost(params, images, start + i, [i as u32, j, k]);
    }
    let row_at = |j: u32, k: u32| &images.moving[voxel_index(0, j, k, d) as usize..][..nx];
    for lane in &mut lanes.slopes {
        lane.resize(nx, 0.0);
    }
    let [sx, sy, sz] = &mut lanes.slopes;
    slopes_along_row(row_at(j, k), sx);
    let neighbours = |c: u32, n: u32| (c.max(1) - 1, (c + 1).min(n - 1));
    let (below, above) = neighbours(j, d[1]);
    slopes_across(row_at(below, k), row_at(above, k), [j, d[1]], sy);
    let (below, above) = neighbours(k, d[2]);
    slopes_across(row_at(j, below), row_at(j, above), [k, d[2]], sz);
    let m = params.mm_to_index.map(|r| Vec3::new(r[0], r[1], r[2]));
    for (i, force) in force.chunks_exact_mut(3).enumerate() {
        let g = sx[i] * m[0] + sy[i] * m[1] + sz[i] * m[2];
        let along = lanes.along[i];
        force.copy_from_slice(&[along * g.x, along * g.y, along * g.z]);
    }
}

/// ∂W/∂i along a row `w` (the shader's slope at each voxel: central inside, one-sided at the
/// ends).
#[inline(always)]
fn slopes_along_row(w: &[f32], out: &mut [f32]) {
    let n = w.len();
    // Inside the row slope is always the central case, written out so that the loop vectorises.
    for i in 1..n.saturating_sub(1) {
        out[i] = (w[i + 1] - w[i - 1]) * 0.5;
    }
    out[0] = difference(w[0], w[1.min(n - 1)], 0, n as u32);
    out[n - 1] = difference(w[n.saturating_sub(2)], w[n - 1], n as u32 - 1, n as u32);
}

/// ∂W/∂j (or ∂k) along a row at coordinate c of n on that axis, from the rows `below` and
/// `above` it (the shader's slope: the same case for the whole row).
#[inline(always)]
fn slopes_across(below: &[f32], above: &[f32], [c, n]: [u32; 2], out: &mut [f32]) {
    for ((o, &lo), &hi) in out.iter_mut().zip(below).zip(above) {
        *o = difference(lo, hi, c, n);
    }
}
