//! CPU twin of shaders/lattice_energy.wgsl.

use super::common::voxel_index;
use crate::abi::EnergyParams;
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

/// Fills `gradient` (3 floats per node: the scaled splat plus ∂E/∂R) and `energy` (1 float per
/// node: the energy of the placements anchored there).
pub fn lattice_energy(
    params: &EnergyParams,
    lattice: &[f32],
    splat: &[f32],
    gradient: &mut [f32],
    energy: &mut [f32],
) {
    let [lx, ly, _, operators] = params.dims;
    gradient
        .par_chunks_mut(3)
        .zip(energy.par_iter_mut())
        .enumerate()
        .for_each(|(n, (g_out, e_out))| {
            let here = IVec3::new(
                (n as u32 % lx) as i32,
                ((n as u32 / lx) % ly) as i32,
                (n as u32 / (lx * ly)) as i32,
            );
            let mut g =
                params.scale[0] * Vec3::new(splat[3 * n], splat[3 * n + 1], splat[3 * n + 2]);
            let mut e = 0.0f32;
            for o in 0..operators as usize {
                let w = params.weights[o][0];
                if placed(params, o, here) {
                    let r = result_at(params, lattice, o, here);
                    e += w * r.dot(r);
                }
                for t in 0..tap_count(params, o) {
                    let p = here - tap(params, o, t);
                    if placed(params, o, p) {
                        g += (2.0 * w * params.coefficients[o][t])
                            * result_at(params, lattice, o, p);
                    }
                }
            }
            g_out.copy_from_slice(&g.to_array());
            *e_out = e;
        });
}
