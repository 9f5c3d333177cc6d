//! CPU twin of shaders/labels/label_index.wgsl (its lookup, labels.wgsl, is twinned in
//! crate::sample).

use crate::abi::LabelParams;
use crate::sample::code_index;
use rayon::prelude::*;

/// Fills `index` (1 float per voxel) with each label's code_index.
pub fn label_index(params: &LabelParams, labels: &[f32], index: &mut [f32]) {
    index
        .par_iter_mut()
        .zip(labels.par_iter())
        .for_each(|(out, &label)| *out = code_index(&params.codes, label) as f32);
}
