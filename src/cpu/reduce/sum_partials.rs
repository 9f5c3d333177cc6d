//! CPU twin of shaders/reduce/sum_partials.wgsl.

use crate::abi::PartialsParams;
use rayon::prelude::*;

/// Fills `out` (groups × values) with each value's partials summed in chunk order, a group of
/// chunks at a time.
pub fn sum_partials<T: Copy + Into<f64> + Sync>(
    params: &PartialsParams,
    partials: &[T],
    out: &mut [f64],
) {
    let [values, chunks, group, _] = params.counts.map(|n| n as usize);
    out.par_iter_mut().enumerate().for_each(|(n, sum)| {
        let (g, v) = (n / values, n % values);
        let (first, last) = (g * group, ((g + 1) * group).min(chunks));
        *sum = (first..last).fold(0.0f64, |s, c| s + partials[c * values + v].into());
    });
}
