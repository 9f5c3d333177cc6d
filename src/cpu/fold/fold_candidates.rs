//! CPU twin of shaders/fold/fold_candidates.wgsl.

use super::contacts::bone_spans;
use super::push_list::Appender;
use crate::abi::CandidateParams;
use crate::cpu::common::dims3;
use rayon::prelude::*;

/// Appends each voxel with a [`LiftRule::lift_code`] above 0 to `list`, in index order.
pub fn fold_candidates(params: &CandidateParams, det: &[f32], held: &[f32], list: Appender) {
    let rule = LiftRule {
        dims: dims3(params.dims),
        threshold: params.threshold,
        spared: params.spared,
    };
    let lifted: Vec<(usize, f32)> = (0..det.len())
        .into_par_iter()
        .map(|v| (v, rule.lift_code(held, v, det[v])))
        .filter(|&(_, code)| code > 0.0)
        .collect();
    let mut list = list;
    let [nx, ny, _] = list.dims;
    for (v, code) in lifted {
        list.append(v, [v % nx, v / nx % ny, v / (nx * ny)], code);
    }
}

/// Twin of shaders/fold/lift_rule.wgsl: which voxels a pass of the fold push lifts.
pub struct LiftRule {
    /// The grid's nx, ny, nz.
    pub dims: [u32; 3],
    /// det J at or below which a voxel is lifted.
    pub threshold: f32,
    /// abi::Spared as a number.
    pub spared: u32,
}

impl LiftRule {
    /// 0 where voxel v, with determinant `det`, is not lifted, 1 where it is, 2 where it is
    /// although a bone contact along one axis (`held`: bone numbers).
    pub fn lift_code(&self, held: &[f32], v: usize, det: f32) -> f32 {
        if det > self.threshold {
            return 0.0;
        }
        let (along_an_axis, enclosed) = bone_spans(held, self.dims, v as u32);
        if enclosed || (along_an_axis && self.spared == 2) {
            return 0.0;
        }
        if along_an_axis {
            2.0
        } else {
            1.0
        }
    }
}
