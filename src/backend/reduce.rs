//! Reductions where the backend computes: chunked sums in f64 and the passes adding partial
//! results (shaders/reduce/, abi::reduce, cpu::reduce, gpu::reduce).

use super::{Core, Element};
use crate::abi::{ListParams, SumParams};
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

    /// The flagged values (> 0) of `flags` and their indices, in index order (`listed` of
    /// them): each chunk of `params` writes its own from its entry in `offsets`, the flagged
    /// values before it ([`flagged`] counts them).
    fn list_flagged(
        &self,
        params: &ListParams,
        flags: &Self::Buffer<f32>,
        offsets: &Self::Buffer<u32>,
        listed: usize,
    ) -> Result<(Self::Buffer<u32>, Self::Buffer<f32>)>;
}

/// Σ (v − shift)^power over all of `values` (`params`), reduced where the backend computes; the
/// chunks' sums come back and are added here.
pub fn total<B: Reduce>(backend: &B, params: &SumParams, values: &B::Buffer<f32>) -> Result<f64> {
    let sums = backend.sum_chunks(params, values)?;
    Ok(backend.download_one(&sums)?.iter().sum())
}

/// Σ (v − shift)^power over all of each of `values` (`params`), the chunks' sums added where
/// the backend computes too: only the totals come back, together, with one wait (where
/// [`total`] brings back every chunk's sum).
pub fn totals<B: Reduce>(
    backend: &B,
    params: &SumParams,
    values: &[&B::Buffer<f32>],
) -> Result<Vec<f64>> {
    let totals = values
        .iter()
        .map(|v| backend.sum_partials(&backend.sum_chunks(params, v)?, 1))
        .collect::<Result<Vec<_>>>()?;
    let totals: Vec<&B::Buffer<f64>> = totals.iter().collect();
    Ok(backend.download(&totals)?.iter().map(|t| t[0]).collect())
}

/// The flagged values (> 0) among the `len` values of `flags` and their indices, in index
/// order: the flags are counted per chunk where the backend computes (one f64 per chunk comes
/// back), each chunk's offset goes up, and only the list comes back, not the array.
pub fn flagged<B: Reduce>(
    backend: &B,
    flags: &B::Buffer<f32>,
    len: usize,
) -> Result<(Vec<u32>, Vec<f32>)> {
    let counts = SumParams::count_above(len, 0.0);
    let counts = backend.download_one(&backend.sum_chunks(&counts, flags)?)?;
    let mut offsets = Vec::with_capacity(counts.len());
    let mut listed = 0u32;
    for count in counts {
        offsets.push(listed);
        listed += count as u32;
    }
    let offsets = backend.upload("offsets of the flagged values", offsets)?;
    let params = ListParams::new(len);
    let (indices, values) = backend.list_flagged(&params, flags, &offsets, listed as usize)?;
    let indices = backend.download_one(&indices)?;
    Ok((indices, backend.download_one(&values)?))
}
