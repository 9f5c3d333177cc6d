//! CPU twin of shaders/fold/fold_candidates.wgsl.

use super::contacts::bone_spans;
use crate::abi::CandidateParams;
use crate::cpu::common::dims3;
use rayon::prelude::*;

/// Fills `flags` with each voxel's [`LiftRule::lift_code`].
pub fn fold_candidates(params: &CandidateParams, det: &[f32], held: &[f32], flags: &mut [f32]) {
    let rule = LiftRule {
        dims: dims3(params.dims),
        threshold: params.threshold,
        spared: params.spared,
    };
    flags.par_iter_mut().enumerate().for_each(|(v, flag)| {
        *flag = rule.lift_code(held, v, det[v]);
    });
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
