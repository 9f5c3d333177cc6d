//! CPU twin of shaders/nonrigid/lattice_energy.wgsl.

use crate::abi::EnergyParams;
use crate::cpu::common::voxel_index;
use glam::{IVec3, Vec3};
use rayon::prelude::*;

fn tap_count(params: &EnergyParams, o: usize) -> usize {
    params.tap_counts[o / 4][o % 4] as usize
}

fn tap(params: &EnergyParams, o: usize, t: usize) -> IVec3 {
    let v = params.taps[4 * o + t];
    IVec3::new(v[0], v[1], v[2])
}

/// Whether every tap of operator o placed at p lies on the lattice.
fn placed(params: &EnergyParams, o: usize, p: IVec3) -> bool {
    let top = IVec3::new(
        params.dims[0] as i32,
        params.dims[1] as i32,
        params.dims[2] as i32,
    );
    (0..tap_count(params, o)).all(|t| {
        let q = p + tap(params, o, t);
        q.cmpge(IVec3::ZERO).all() && q.cmplt(top).all()
    })
}

/// Σ_t c_ot R(p + t) for a placement that lies on the lattice.
fn result_at(params: &EnergyParams, lattice: &[f32], o: usize, p: IVec3) -> Vec3 {
    let d = [params.dims[0], params.dims[1], params.dims[2]];
    let mut sum = Vec3::ZERO;
    for t in 0..tap_count(params, o) {
        let q = (p + tap(params, o, t)).as_uvec3();
        let n = 3 * voxel_index(q.x, q.y, q.z, d) as usize;
        let r = Vec3::new(lattice[n], lattice[n + 1], lattice[n + 2]);
        sum += params.coefficients[o][t] * r;
    }
    sum
}

/// Each operator's result at every node, `None` where its placement leaves the lattice (index
/// node · operators + o): the shader recomputes a result for each tap that reads it, the twin
/// computes it once (the same sums, so the same bits).
fn results(params: &EnergyParams, lattice: &[f32]) -> Vec<Option<Vec3>> {
    let [lx, ly, lz, _] = params.dims;
    let nodes = (lx * ly * lz) as usize;
    let operators = params.operators as usize;
    let mut out = vec![None; nodes * operators];
    out.par_chunks_mut(operators.max(1))
        .enumerate()
        .for_each(|(n, here_results)| {
            let here = node(params, n);
            for (o, r) in here_results.iter_mut().enumerate() {
                *r = placed(params, o, here).then(|| result_at(params, lattice, o, here));
            }
        });
    out
}

/// Lattice coordinates of node n.
fn node(params: &EnergyParams, n: usize) -> IVec3 {
    let [lx, ly, _, _] = params.dims;
    IVec3::new(
        (n as u32 % lx) as i32,
        ((n as u32 / lx) % ly) as i32,
        (n as u32 / (lx * ly)) as i32,
    )
}

/// Fills `gradient` (3 floats per node: the scaled splat plus ∂E/∂R) and `energy` (1 float per
/// node: the energy of the placements anchored there).
pub fn lattice_energy(
    params: &EnergyParams,
    lattice: &[f32],
    splat: &[f32],
    gradient: &mut [f32],
    energy: &mut [f32],
) {
    let [lx, ly, lz, _] = params.dims;
    let operators = params.operators as usize;
    let results = results(params, lattice);
    let top = IVec3::new(lx as i32, ly as i32, lz as i32);
    let result = |o: usize, p: IVec3| -> Option<Vec3> {
        let inside = p.cmpge(IVec3::ZERO).all() && p.cmplt(top).all();
        let n = || voxel_index(p.x as u32, p.y as u32, p.z as u32, [lx, ly, lz]) as usize;
        inside.then(|| results[n() * operators + o]).flatten()
    };
    gradient
        .par_chunks_mut(3)
        .zip(energy.par_iter_mut())
        .enumerate()
        .for_each(|(n, (g_out, e_out))| {
            let here = node(params, n);
            let mut g = params.scale * Vec3::new(splat[3 * n], splat[3 * n + 1], splat[3 * n + 2]);
            let mut e = 0.0f32;
            for o in 0..operators {
                let w = params.weights[o][0];
                if let Some(r) = results[n * operators + o] {
                    e += w * r.dot(r);
                }
                for t in 0..tap_count(params, o) {
                    if let Some(r) = result(o, here - tap(params, o, t)) {
                        g += (2.0 * w * params.coefficients[o][t]) * r;
                    }
                }
            }
            g_out.copy_from_slice(&g.to_array());
            *e_out = e;
        });
}
