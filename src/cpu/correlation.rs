//! CPU twins of the correlation family's kernels (shaders/correlation/).

mod lncc;
mod lncc_gradient;
mod lncc_terms;
mod local_moments;

use super::{filled, filled_pair, CpuBackend};
use crate::abi::{LnccParams, LnccTermsParams, LocalMomentsParams, RbfGradParams};
use crate::backend::correlation::Correlation;
use crate::error::Result;
use std::sync::Arc;

impl Correlation for CpuBackend {
    fn local_moments(
        &self,
        params: &LocalMomentsParams,
        input: &Arc<Vec<f32>>,
        other: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.values(), |out| {
            local_moments::local_moments(params, input, other, out)
        })
    }

    fn lncc(&self, params: &LnccParams, sums: &Arc<Vec<f32>>) -> Result<Arc<Vec<f32>>> {
        filled(2 * params.chunks(), |out| lncc::lncc(params, sums, out))
    }

    fn lncc_terms(
        &self,
        params: &LnccTermsParams,
        sums: &Arc<Vec<f32>>,
        covered: &Arc<Vec<f32>>,
    ) -> Result<(Arc<Vec<f32>>, Arc<Vec<f32>>)> {
        filled_pair([params.values(), params.rows()], |terms, rows| {
            lncc_terms::lncc_terms(params, sums, covered, terms, rows);
        })
    }

    fn lncc_gradient(
        &self,
        params: &RbfGradParams,
        lattice: &Arc<Vec<f32>>,
        moving: &Arc<Vec<f32>>,
        fixed: &Arc<Vec<f32>>,
        summed: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(3 * params.voxels(), |out| {
            lncc_gradient::lncc_gradient(params, lattice, [moving, fixed], summed, out)
        })
    }
}
