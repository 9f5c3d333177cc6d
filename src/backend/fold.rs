//! Folds of a field: its Jacobian determinant and the fold statistics, and the fold repair's
//! masks and smoothing (shaders/fold/, abi::fold, cpu::fold, gpu::fold).

use super::Core;
use crate::abi::{
    AdvanceParams, BoneLookupParams, CandidateParams, DilateParams, JacobianParams, PushParams,
    RefreshParams, ThresholdParams,
};
use crate::error::Result;

/// Kernels finding and repairing folds.
pub trait Fold: Core {
    /// det(I + du/dx) of the map x → x + u(x) at every voxel of the field's grid: where it is
    /// ≤ 0 the map folds.
    fn jacobian(
        &self,
        params: &JacobianParams,
        field: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// Per chunk of abi::STATS_CHUNK voxels of a Jacobian determinant `det`, the bone contacts
    /// at or below the threshold apart (voxels whose stencil spans two bones `held`: along one
    /// axis, or all six neighbours held; `held` values are bone numbers): its minimum, the
    /// voxels ≤ 0, the voxels ≤ `params`' threshold, and those of them not `held` (> 0); then
    /// the bone contacts ≤ 0 (shaders/fold/fold_stats.wgsl).
    fn fold_stats(
        &self,
        params: &ThresholdParams,
        det: &Self::Buffer<f32>,
        held: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// 1 on the voxels not `held` whose `value` is at or below `params`' threshold, else 0.
    fn mark_at_most(
        &self,
        params: &ThresholdParams,
        value: &Self::Buffer<f32>,
        held: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// One axis of a box dilation of `mask` (`params`; marked where > 0, 1 or 0 out),
    /// clearing the `held` voxels when `params` says.
    fn dilate(
        &self,
        params: &DilateParams,
        mask: &Self::Buffer<f32>,
        held: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// One sweep of local smoothing of `field` over `region`: each voxel there takes the mean
    /// of its 27 neighbours unless that carries its source point into a bone (`labels`,
    /// `params`' codes) it was not in.
    fn fold_smooth(
        &self,
        params: &BoneLookupParams,
        field: &Self::Buffer<f32>,
        region: &Self::Buffer<f32>,
        labels: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// The first list of a pass of the fold push (shaders/fold/push_list.wgsl): the voxels it
    /// lifts (det J at or below `params`' threshold, those it spares aside, by the bones
    /// `held`: bone numbers, 0 for tissue), appended to their colours' buckets of `next` and
    /// counted in `state` (abi::push_state: the next counts, and those not bone contacts).
    fn fold_candidates(
        &self,
        params: &CandidateParams,
        det_and_held: (&Self::Buffer<f32>, &Self::Buffer<f32>),
        next: &mut Self::Buffer<u32>,
        state: &mut Self::Buffer<u32>,
    ) -> Result<()>;

    /// One colour's pushes in a sweep of the fold push (shaders/fold/fold_push.wgsl): each of
    /// the colour's voxels in the sweep's list `voxels` (as many as `state` counts) still
    /// folded moves its stencil neighbours to lift it, none `rigid` (> 0), none into a bone
    /// of the source `labels`. `field` and `blocked` (the sweep each voxel was last blocked
    /// in) are written in place: buffers made for this (Core::duplicate, Core::zeros) and
    /// shared with nothing else. `args` are fold_advance's workgroup counts: a GPU dispatches
    /// by them, the CPU twin reads the count in `state`.
    fn fold_push(
        &self,
        params: &PushParams,
        voxels: &Self::Buffer<u32>,
        rigid_and_labels: (&Self::Buffer<f32>, &Self::Buffer<f32>),
        field: &mut Self::Buffer<f32>,
        blocked: &mut Self::Buffer<u32>,
        state_and_args: (&Self::Buffer<u32>, &Self::Buffer<u32>),
    ) -> Result<()>;

    /// After a sweep of the fold push, the next sweep's list: the voxels within two steps of
    /// the sweep's list `voxels` that the pass lifts now (the pushes can have changed det J
    /// of `field` there and nowhere else; `held` as for fold_candidates), each looked at once
    /// (stamped in `looked` with the sweep), appended to `next` and counted in `state` (`args`
    /// as for fold_push).
    fn fold_refresh(
        &self,
        params: &RefreshParams,
        lists: (&Self::Buffer<u32>, &mut Self::Buffer<u32>),
        field_and_held: (&Self::Buffer<f32>, &Self::Buffer<f32>),
        looked: &mut Self::Buffer<u32>,
        state_and_args: (&mut Self::Buffer<u32>, &Self::Buffer<u32>),
    ) -> Result<()>;

    /// Between two sweeps of the fold push (shaders/fold/fold_advance.wgsl): ends the pass
    /// or makes the next list the sweep's, in `state`, and writes the sweep's workgroup
    /// counts into `args` (abi::push_state::ARGS_LEN).
    fn fold_advance(
        &self,
        params: &AdvanceParams,
        state: &mut Self::Buffer<u32>,
        args: &mut Self::Buffer<u32>,
    ) -> Result<()>;
}
