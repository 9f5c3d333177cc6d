//! Folds of a field: its Jacobian determinant and the fold statistics, and the fold repair's
//! masks and smoothing (shaders/fold/, abi::fold, cpu::fold, gpu::fold).

use super::Core;
use crate::abi::{BoneLookupParams, DilateParams, JacobianParams, ThresholdParams};
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
}
