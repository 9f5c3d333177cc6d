//! CPU twins of the fold family's kernels (shaders/fold/).

mod dilate;
mod fold_smooth;
mod fold_stats;
mod jacobian;
mod mark_at_most;
mod threshold;

use super::{filled, CpuBackend};
use crate::abi::{
    BoneLookupParams, DilateParams, JacobianParams, ThresholdParams, FOLD_STATS_WIDTH,
};
use crate::backend::fold::Fold;
use crate::error::Result;
use std::sync::Arc;

impl Fold for CpuBackend {
    fn jacobian(&self, params: &JacobianParams, field: &Arc<Vec<f32>>) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            jacobian::jacobian(params, field, out)
        })
    }

    fn fold_stats(
        &self,
        params: &ThresholdParams,
        det: &Arc<Vec<f32>>,
        held: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(FOLD_STATS_WIDTH * params.chunks(), |out| {
            fold_stats::fold_stats(params, det, held, out)
        })
    }

    fn mark_at_most(
        &self,
        params: &ThresholdParams,
        value: &Arc<Vec<f32>>,
        held: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            mark_at_most::mark_at_most(params, value, held, out)
        })
    }

    fn dilate(
        &self,
        params: &DilateParams,
        mask: &Arc<Vec<f32>>,
        held: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            dilate::dilate(params, mask, held, out)
        })
    }

    fn fold_smooth(
        &self,
        params: &BoneLookupParams,
        field: &Arc<Vec<f32>>,
        region: &Arc<Vec<f32>>,
        labels: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(3 * params.voxels(), |out| {
            fold_smooth::fold_smooth(params, field, region, labels, out)
        })
    }
}
