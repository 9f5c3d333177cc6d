//! CPU twin of shaders/fold/fold_refresh.wgsl: the voxels within two steps of the listed ones
//! stamped in the list's order, each first seen once, their codes worked out at once (on every
//! core), then the ones to lift appended in that order.

use super::fold_candidates::LiftRule;
use super::push_list::{listed, Appender};
use super::stencil::Stencil;
use crate::abi::push_state::SWEEP;
use crate::abi::RefreshParams;
use rayon::prelude::*;

/// Appends to `list` the voxels within two steps (L1) of each of the sweep's list `voxels`
/// that the pass lifts now, each looked at once (stamped in `stamps` with the sweep).
pub fn fold_refresh(
    params: &RefreshParams,
    voxels: &[u32],
    (field, held): (&[f32], &[f32]),
    stamps: &mut [u32],
    list: Appender,
) {
    let stencil = Stencil::new(params.dims, params.mm_to_index);
    let rule = LiftRule {
        dims: [params.dims[0], params.dims[1], params.dims[2]],
        threshold: params.threshold,
        spared: params.spared,
    };
    let d = stencil.dims();
    let sweep = list.state[SWEEP];
    let mut near = Vec::new();
    let steps = within_two_steps();
    for n in listed(voxels, list.state, d) {
        let c = stencil.voxel_of(n as usize).map(|i| i as i64);
        for step in &steps {
            let p: [i64; 3] = std::array::from_fn(|a| c[a] + step[a]);
            if (0..3).any(|a| p[a] < 0 || p[a] >= d[a] as i64) {
                continue;
            }
            let q = p.map(|i| i as usize);
            let v = q[0] + d[0] * (q[1] + d[1] * q[2]);
            if stamps[v] < sweep {
                stamps[v] = sweep;
                near.push((v, q));
            }
        }
    }
    let codes: Vec<f32> = near
        .par_iter()
        .map(|&(v, q)| rule.lift_code(held, v, stencil.det_at(field, q, v)))
        .collect();
    let mut list = list;
    for (&(v, q), code) in near.iter().zip(codes) {
        if code > 0.0 {
            list.append(v, q, code);
        }
    }
}

/// The 25 offsets within two steps (L1) of a voxel, z slowest and x fastest, as the shader
/// visits them.
fn within_two_steps() -> Vec<[i64; 3]> {
    let range = || -2i64..=2;
    range()
        .flat_map(|dz| range().flat_map(move |dy| range().map(move |dx| [dx, dy, dz])))
        .filter(|s| s.iter().map(|x| x.abs()).sum::<i64>() <= 2)
        .collect()
}
