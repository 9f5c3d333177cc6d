//! CPU twin of shaders/sum_chunks.wgsl.

use crate::abi::SumParams;
use rayon::prelude::*;

/// Fills `sums` with the f64 sum of each chunk of `values`, in index order.
pub fn sum_chunks(params: &SumParams, values: &[f32], sums: &mut [f64]) {
    let chunk = params.counts[1] as usize;
    sums.par_iter_mut().enumerate().for_each(|(c, sum)| {
        let end = ((c + 1) * chunk).min(values.len());
        *sum = values[c * chunk..end]
            .iter()
            .fold(0.0f64, |s, &v| s + v as f64);
    });
}
