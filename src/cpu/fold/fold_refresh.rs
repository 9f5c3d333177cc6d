//! CPU twin of shaders/fold/fold_refresh.wgsl.

use super::fold_candidates::LiftRule;
use super::stencil::Stencil;
use crate::abi::RefreshParams;
use rayon::prelude::*;

/// Refreshes `flags` within two steps (L1) of each of the listed `voxels`
/// (`params.first..params.end`): each voxel's lift code now.
pub fn fold_refresh(
    params: &RefreshParams,
    voxels: &[u32],
    (field, held): (&[f32], &[f32]),
    flags: &mut [f32],
) {
    let stencil = Stencil::new(params.dims, params.mm_to_index);
    let rule = LiftRule {
        dims: [params.dims[0], params.dims[1], params.dims[2]],
        threshold: params.threshold,
        spared: params.spared,
    };
    let d = stencil.dims();
    let codes: Vec<Vec<(usize, f32)>> = voxels[params.first as usize..params.end as usize]
        .par_iter()
        .map(|&n| {
            let c = stencil.voxel_of(n as usize).map(|i| i as i64);
            let mut codes = Vec::with_capacity(25);
            for dz in -2i64..=2 {
                for dy in -2i64..=2 {
                    for dx in -2i64..=2 {
                        let p = [c[0] + dx, c[1] + dy, c[2] + dz];
                        let near = dx.abs() + dy.abs() + dz.abs() <= 2;
                        if !near || (0..3).any(|a| p[a] < 0 || p[a] >= d[a] as i64) {
                            continue;
                        }
                        let q = p.map(|i| i as usize);
                        let v = q[0] + d[0] * (q[1] + d[1] * q[2]);
                        codes.push((v, rule.lift_code(held, v, stencil.det_at(field, q, v))));
                    }
                }
            }
            codes
        })
        .collect();
    for (v, code) in codes.into_iter().flatten() {
        flags[v] = code;
    }
}
