//! CPU twin of shaders/reduce/sum_chunks.wgsl.

use crate::abi::SumParams;
use rayon::prelude::*;

/// Fills `sums` with the f64 sum of (v − shift)^power over each chunk of `values`, in index
/// order; power 0 counts the values above the shift.
pub fn sum_chunks(params: &SumParams, values: &[f32], sums: &mut [f64]) {
    let chunk = params.counts[1] as usize;
    let power = params.power;
    let shift = params.shift as f64;
    sums.par_iter_mut().enumerate().for_each(|(c, sum)| {
        let end = ((c + 1) * chunk).min(values.len());
        *sum = values[c * chunk..end].iter().fold(0.0f64, |s, &v| {
            let d = v as f64 - shift;
            s + match power {
                0 => (d > 0.0) as u8 as f64,
                2 => d * d,
                _ => d,
            }
        });
    });
}
