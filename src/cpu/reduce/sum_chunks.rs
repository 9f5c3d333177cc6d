//! CPU twin of shaders/reduce/sum_chunks.wgsl.

use crate::abi::SumParams;
use rayon::prelude::*;

/// Fills `sums` with the f64 sum of (v − shift)^power over each chunk of `values`, in index
/// order.
pub fn sum_chunks(params: &SumParams, values: &[f32], sums: &mut [f64]) {
    let chunk = params.counts[1] as usize;
    let squares = params.power == 2;
    let shift = params.shift as f64;
    sums.par_iter_mut().enumerate().for_each(|(c, sum)| {
        let end = ((c + 1) * chunk).min(values.len());
        *sum = values[c * chunk..end].iter().fold(0.0f64, |s, &v| {
            let d = v as f64 - shift;
            s + if squares { d * d } else { d }
        });
    });
}
