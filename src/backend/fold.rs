//! Folds of a field: its Jacobian determinant and the fold statistics, and the fold repair's
//! masks and smoothing (shaders/fold/, abi::fold, cpu::fold, gpu::fold).

use super::Core;
use crate::abi::{
    BoneLookupParams, CandidateParams, DilateParams, JacobianParams, PushParams, RefreshParams,
    ThresholdParams,
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

    /// One axis of a box dilation of a 0/1 `mask` (`params`), clearing the `held` voxels
    /// when `params` says.
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

    /// On the voxels a pass of the fold push lifts (det J at or below `params`' threshold,
    /// those it spares aside, by the bones `held`: bone numbers, 0 for tissue) 1, or 2 where
    /// the voxel is a bone contact along one axis (a pass that lifts those); else 0.
    fn fold_candidates(
        &self,
        params: &CandidateParams,
        det: &Self::Buffer<f32>,
        held: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// One colour's pushes in a sweep of the fold push (shaders/fold/fold_push.wgsl): each of
    /// `params`' range of `voxels` still folded moves its stencil neighbours to lift it, none
    /// `rigid` (> 0), none into a bone of the source `labels`. `field` and `blocked` (the sweep
    /// each voxel was last blocked in) are written in place: buffers made for this
    /// (Core::duplicate, Core::zeros) and shared with nothing else.
    fn fold_push(
        &self,
        params: &PushParams,
        voxels: &Self::Buffer<u32>,
        rigid_and_labels: (&Self::Buffer<f32>, &Self::Buffer<f32>),
        field: &mut Self::Buffer<f32>,
        blocked: &mut Self::Buffer<u32>,
    ) -> Result<()>;

    /// After a sweep of the fold push, the `flags` of fold_candidates refreshed within two
    /// steps of each of `params`' range of the sweep's `voxels`, where the sweep's pushes can
    /// have changed det J of `field` (`held` as for fold_candidates). `flags` is written in
    /// place (a buffer made for this and shared with nothing else).
    fn fold_refresh(
        &self,
        params: &RefreshParams,
        voxels: &Self::Buffer<u32>,
        field_and_held: (&Self::Buffer<f32>, &Self::Buffer<f32>),
        flags: &mut Self::Buffer<f32>,
    ) -> Result<()>;
}
