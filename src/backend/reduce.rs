//! Reductions where the backend computes: chunked sums in f64 and the passes adding partial
//! results (shaders/reduce/, abi::reduce, cpu::reduce, gpu::reduce).

use super::{Core, Element};
use crate::abi::SumParams;
use crate::error::Result;

/// Kernels reducing a buffer to a few sums.
pub trait Reduce: Core {
    /// Per-chunk partial results of `values` values each, added in chunk order (in groups,
    /// abi::PartialsParams::passes), in f64.
    fn sum_partials<T: Element>(
        &self,
        partials: &Self::Buffer<T>,
        values: usize,
    ) -> Result<Self::Buffer<f64>>;

    /// Sums of (v − shift)^power over chunks of abi::SUM_CHUNK values, in f64 (`params`).
    fn sum_chunks(
        &self,
        params: &SumParams,
        values: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f64>>;
}

/// Σ (v − shift)^power over all of `values` (`params`), reduced where the backend computes; the
/// chunks' sums come back and are added here.
pub fn total<B: Reduce>(backend: &B, params: &SumParams, values: &B::Buffer<f32>) -> Result<f64> {
    let sums = backend.sum_chunks(params, values)?;
    Ok(backend.download_one(&sums)?.iter().sum())
}
