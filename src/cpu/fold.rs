//! CPU twins of the fold family's kernels (shaders/fold/).

mod contacts;
mod dilate;
mod fold_advance;
mod fold_candidates;
mod fold_push;
mod fold_refresh;
mod fold_smooth;
mod fold_stats;
mod jacobian;
mod mark_at_most;
mod push_list;
mod stencil;
mod threshold;

use super::{filled, CpuBackend};
use crate::abi::{
    AdvanceParams, BoneLookupParams, CandidateParams, DilateParams, JacobianParams, PushParams,
    RefreshParams, ThresholdParams, FOLD_STATS_WIDTH,
};
use crate::backend::fold::Fold;
use crate::cpu::common::dims3;
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

    fn fold_candidates(
        &self,
        params: &CandidateParams,
        (det, held): (&Arc<Vec<f32>>, &Arc<Vec<f32>>),
        next: &mut Arc<Vec<u32>>,
        state: &mut Arc<Vec<u32>>,
    ) -> Result<()> {
        // Unshared as the trait asks, so nothing is copied.
        let list = push_list::Appender {
            dims: dims3(params.dims).map(|n| n as usize),
            next: Arc::make_mut(next).as_mut_slice(),
            state: Arc::make_mut(state).as_mut_slice(),
        };
        fold_candidates::fold_candidates(params, det, held, list);
        Ok(())
    }

    fn fold_push(
        &self,
        params: &PushParams,
        voxels: &Arc<Vec<u32>>,
        (rigid, labels): (&Arc<Vec<f32>>, &Arc<Vec<f32>>),
        field: &mut Arc<Vec<f32>>,
        blocked: &mut Arc<Vec<u32>>,
        (state, _): (&Arc<Vec<u32>>, &Arc<Vec<u32>>),
    ) -> Result<()> {
        let buffers = fold_push::PushBuffers {
            voxels,
            state,
            rigid,
            labels,
            field: Arc::make_mut(field).as_mut_slice(),
            blocked: Arc::make_mut(blocked).as_mut_slice(),
        };
        fold_push::fold_push(params, buffers);
        Ok(())
    }

    fn fold_refresh(
        &self,
        params: &RefreshParams,
        (voxels, next): (&Arc<Vec<u32>>, &mut Arc<Vec<u32>>),
        (field, held): (&Arc<Vec<f32>>, &Arc<Vec<f32>>),
        looked: &mut Arc<Vec<u32>>,
        (state, _): (&mut Arc<Vec<u32>>, &Arc<Vec<u32>>),
    ) -> Result<()> {
        let list = push_list::Appender {
            dims: dims3(params.dims).map(|n| n as usize),
            next: Arc::make_mut(next).as_mut_slice(),
            state: Arc::make_mut(state).as_mut_slice(),
        };
        let stamps = Arc::make_mut(looked).as_mut_slice();
        fold_refresh::fold_refresh(params, voxels, (field, held), stamps, list);
        Ok(())
    }

    fn fold_advance(
        &self,
        params: &AdvanceParams,
        state: &mut Arc<Vec<u32>>,
        args: &mut Arc<Vec<u32>>,
    ) -> Result<()> {
        let args = Arc::make_mut(args).as_mut_slice();
        fold_advance::fold_advance(params, Arc::make_mut(state).as_mut_slice(), args);
        Ok(())
    }
}
