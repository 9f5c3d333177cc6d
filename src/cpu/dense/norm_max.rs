//! CPU twin of shaders/dense/norm_max.wgsl.

use crate::abi::dense::NormParams;
use rayon::prelude::*;

/// Fills `maxima` (one per chunk) with the largest vector length of each chunk of `field`.
pub fn norm_max(params: &NormParams, field: &[f32], maxima: &mut [f32]) {
    let (vectors, per_chunk) = (params.vectors as usize, params.per_chunk as usize);
    maxima.par_iter_mut().enumerate().for_each(|(c, largest)| {
        *largest = (c * per_chunk..((c + 1) * per_chunk).min(vectors))
            .map(|v| {
                let u = &field[3 * v..3 * v + 3];
                (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt()
            })
            .fold(0.0, f32::max);
    });
}
