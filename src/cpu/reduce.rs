//! CPU twins of the reduce family's kernels (shaders/reduce/).

mod list_flagged;
mod sum_chunks;
mod sum_partials;

use super::{filled, zeroed, CpuBackend};
use crate::abi::{ListParams, PartialsParams, SumParams};
use crate::backend::reduce::Reduce;
use crate::backend::Element;
use crate::error::Result;
use std::sync::Arc;

impl Reduce for CpuBackend {
    fn sum_partials<T: Element>(
        &self,
        partials: &Arc<Vec<T>>,
        values: usize,
    ) -> Result<Arc<Vec<f64>>> {
        let mut sums: Option<Vec<f64>> = None;
        for pass in PartialsParams::passes(values, partials.len() / values.max(1)) {
            let mut out = zeroed::<f64>(pass.groups() * values);
            match &sums {
                None => sum_partials::sum_partials(&pass, partials, &mut out),
                Some(earlier) => sum_partials::sum_partials(&pass, earlier, &mut out),
            }
            sums = Some(out);
        }
        Ok(Arc::new(sums.expect("at least one pass")))
    }

    fn sum_chunks(&self, params: &SumParams, values: &Arc<Vec<f32>>) -> Result<Arc<Vec<f64>>> {
        filled(params.chunks(), |out| {
            sum_chunks::sum_chunks(params, values, out)
        })
    }

    fn list_flagged(
        &self,
        params: &ListParams,
        flags: &Arc<Vec<f32>>,
        offsets: &Arc<Vec<u32>>,
        listed: usize,
    ) -> Result<(Arc<Vec<u32>>, Arc<Vec<f32>>)> {
        let (mut indices, mut values) = (zeroed(listed), zeroed(listed));
        list_flagged::list_flagged(params, flags, offsets, &mut indices, &mut values);
        Ok((Arc::new(indices), Arc::new(values)))
    }
}
