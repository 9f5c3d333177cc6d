//! CPU twin of shaders/nonrigid/rbf_lattice.wgsl (with shaders/nonrigid/rbf_nodes.wgsl).
//!
//! Each node's sum runs in the shader's order (the affine part, then the points in order); the
//! twin walks a run of nodes at a time through each point, so the loop over nodes vectorises.

use super::rbf_nodes::node_position;
use crate::abi::RbfLatticeParams;
use rayon::prelude::*;

/// Nodes one task evaluates (a run long enough for the loop over them to vectorise well).
const NODES_PER_TASK: usize = 256;

/// Fills `values` (3 floats per node) with the warp R at every lattice node.
pub fn rbf_lattice(
    params: &RbfLatticeParams,
    geometry: &[f64],
    spline: &[f64],
    values: &mut [f32],
) {
    values
        .par_chunks_mut(3 * NODES_PER_TASK)
        .enumerate()
        .for_each(|(task, out)| nodes_run(params, geometry, spline, task * NODES_PER_TASK, out));
}

/// R at the nodes first .. first + out.len() / 3; also compiled for AVX2 (crate::cpu's
/// notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn nodes_run(
    params: &RbfLatticeParams,
    geometry: &[f64],
    spline: &[f64],
    first: usize,
    out: &mut [f32],
) {
    let [lx, ly, _, _] = params.lattice;
    let points = params.points;
    let s = spline;
    // Coordinates and sums by axis, so the loop over the run's nodes vectorises.
    let x: Vec<[f64; 3]> = (first..first + out.len() / 3)
        .map(|n| {
            let a = [n as u32 % lx, (n as u32 / lx) % ly, n as u32 / (lx * ly)];
            node_position(geometry, a, params.step)
        })
        .collect();
    let [xs, ys, zs] = [0, 1, 2].map(|a| x.iter().map(|p| p[a]).collect::<Vec<f64>>());
    let mut r: [Vec<f64>; 3] = std::array::from_fn(|k| {
        x.iter()
            .map(|x| s[k] + s[3 + k] * x[0] + s[6 + k] * x[1] + s[9 + k] * x[2])
            .collect()
    });
    for p in 0..points as usize {
        let o = 12 + 6 * p;
        let (cx, cy, cz) = (s[o], s[o + 1], s[o + 2]);
        let [rx, ry, rz] = &mut r;
        for n in 0..xs.len() {
            // rbf_nodes.wgsl's cube_of_distance(x[n], centre), written out by lane.
            let (dx, dy, dz) = (xs[n] - cx, ys[n] - cy, zs[n] - cz);
            let d = (dx * dx + dy * dy + dz * dz).sqrt();
            let f = d * d * d;
            rx[n] += s[o + 3] * f;
            ry[n] += s[o + 4] * f;
            rz[n] += s[o + 5] * f;
        }
    }
    for (n, out) in out.chunks_exact_mut(3).enumerate() {
        for k in 0..3 {
            out[k] = r[k][n] as f32;
        }
    }
}
