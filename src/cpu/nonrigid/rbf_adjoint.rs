//! CPU twin of shaders/nonrigid/rbf_adjoint.wgsl.
//!
//! Each output row sums a chunk's nodes in the shader's order; the twin walks the chunk once
//! for a block of rows, so the loop over a block's control points vectorises.

use super::rbf_nodes::node_position;
use crate::abi::RbfLatticeParams;
use rayon::prelude::*;

/// Output rows a task sums together.
const BLOCK: usize = 8;

/// Affine row k's term at x: 1, x, y or z.
fn affine_term(k: usize, x: [f64; 3]) -> f64 {
    match k {
        0 => 1.0,
        k => x[k - 1],
    }
}

/// Fills `partials` (per chunk of nodes: 3 f64 per control point, then 3 per affine row) with
/// the cost's gradient with respect to the RBF's coefficients, from its gradient at the nodes.
pub fn rbf_adjoint(
    params: &RbfLatticeParams,
    geometry: &[f64],
    spline: &[f64],
    node_gradient: &[f32],
    partials: &mut [f64],
) {
    let rows = params.rows();
    let chunk = params.chunk_nodes();
    let nodes = params.nodes();
    partials
        .par_chunks_mut(3 * rows)
        .enumerate()
        .for_each(|(c, out)| {
            // The chunk's node positions, computed as the shader does, once for all its rows.
            let l = [params.lattice[0], params.lattice[1], params.lattice[2]];
            let positions: Vec<[f64; 3]> = (c * chunk..((c + 1) * chunk).min(nodes))
                .map(|n| {
                    let a = [
                        n as u32 % l[0],
                        (n as u32 / l[0]) % l[1],
                        n as u32 / (l[0] * l[1]),
                    ];
                    node_position(geometry, a, params.step)
                })
                .collect();
            let gradient = &node_gradient[3 * c * chunk..3 * (c * chunk + positions.len())];
            out.par_chunks_mut(3 * BLOCK)
                .enumerate()
                .for_each(|(block, rows)| {
                    sum_block(params, spline, &positions, gradient, block, rows)
                });
        });
}

/// One chunk's sums for output rows block · BLOCK .. (as many as `out` holds), from the chunk's
/// node `positions` and `gradient` (3 floats per node); also compiled for AVX2 (crate::cpu's
/// notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn sum_block(
    params: &RbfLatticeParams,
    spline: &[f64],
    positions: &[[f64; 3]],
    gradient: &[f32],
    block: usize,
    out: &mut [f64],
) {
    let points = params.points();
    let first = block * BLOCK;
    let rows_here = out.len() / 3;
    // Rows first .. first + BLOCK: control points (their centres; a block's spare lanes repeat
    // its first centre and are discarded), then affine rows.
    let centre = |r: usize| {
        let o = 12 + 6 * (first + r).min(points.saturating_sub(1));
        [spline[o], spline[o + 1], spline[o + 2]]
    };
    let centres: [[f64; 3]; BLOCK] = std::array::from_fn(centre);
    // Coordinates and sums by axis, so the loop over the block's lanes vectorises.
    let [cx, cy, cz] = [0, 1, 2].map(|a| centres.map(|c| c[a]));
    let mut point_sums = [[0.0f64; BLOCK]; 3];
    let mut affine_sums = [[0.0f64; 3]; BLOCK];
    for (x, g) in positions.iter().zip(gradient.chunks_exact(3)) {
        let (x, g) = (*x, [0, 1, 2].map(|c| g[c] as f64));
        if first < points {
            let [sx, sy, sz] = &mut point_sums;
            for r in 0..BLOCK {
                // rbf_nodes.wgsl's cube_of_distance(x, centres[r]), written out by lane.
                let (dx, dy, dz) = (x[0] - cx[r], x[1] - cy[r], x[2] - cz[r]);
                let d = (dx * dx + dy * dy + dz * dz).sqrt();
                let w = d * d * d;
                sx[r] += g[0] * w;
                sy[r] += g[1] * w;
                sz[r] += g[2] * w;
            }
        }
        let affine_rows = (points.max(first) - first)..rows_here;
        for (r, sum) in affine_sums
            .iter_mut()
            .enumerate()
            .take(affine_rows.end)
            .skip(affine_rows.start)
        {
            let w = affine_term(first + r - points, x);
            for a in 0..3 {
                sum[a] += g[a] * w;
            }
        }
    }
    for (r, row) in out.chunks_exact_mut(3).enumerate() {
        if first + r < points {
            row.copy_from_slice(&point_sums.map(|axis| axis[r]));
        } else {
            row.copy_from_slice(&affine_sums[r]);
        }
    }
}
