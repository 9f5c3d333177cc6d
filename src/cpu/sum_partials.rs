//! CPU twin of shaders/sum_partials.wgsl.

use crate::abi::PartialsParams;
use rayon::prelude::*;

/// Fills `out` with each value's partials summed in chunk order.
pub fn sum_partials(params: &PartialsParams, partials: &[f64], out: &mut [f64]) {
    let [values, chunks, _, _] = params.counts.map(|n| n as usize);
    out.par_iter_mut().enumerate().for_each(|(v, sum)| {
        *sum = (0..chunks).fold(0.0f64, |s, c| s + partials[c * values + v]);
    });
}
