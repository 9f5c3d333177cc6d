//! CPU twin of shaders/fold/mark_at_most.wgsl.

use super::threshold::is_held;
use crate::abi::ThresholdParams;
use rayon::prelude::*;

/// Fills `mark` (1 float per voxel) with 1 on the voxels not held whose value is at most the
/// threshold.
pub fn mark_at_most(params: &ThresholdParams, value: &[f32], held: &[f32], mark: &mut [f32]) {
    let threshold = params.threshold;
    mark.par_iter_mut().enumerate().for_each(|(v, out)| {
        *out = if value[v] <= threshold && !is_held(held[v]) {
            1.0
        } else {
            0.0
        };
    });
}
