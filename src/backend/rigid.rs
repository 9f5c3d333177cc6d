//! A bone's rigid registration: Gauss-Newton sums and candidate scores (shaders/rigid/,
//! abi::rigid, cpu::rigid, gpu::rigid).

use super::Core;
use crate::abi::{RigidParams, ScoreParams};
use crate::error::Result;

/// The images one step of a bone's rigid registration compares, at one pyramid level.
pub struct BoneImages<'a, T: ?Sized> {
    /// The source S.
    pub source: &'a T,
    /// The bone's region on the source grid (≥ 0.5 inside).
    pub mask: &'a T,
    /// The target T, sampled through the motion.
    pub target: &'a T,
}

/// Kernels of a bone's rigid registration.
pub trait Rigid: Core {
    /// Per-column Gauss-Newton sums of a bone's rigid registration (abi::RIGID_SUMS per
    /// column of the source, layout of shaders/rigid/rigid_gn.wgsl) at the motion in `params`.
    fn rigid_sums(
        &self,
        params: &RigidParams,
        images: &BoneImages<Self::Buffer<f32>>,
    ) -> Result<Self::Buffer<f32>>;

    /// Per-column sums (abi::SCORE_SUMS: Σ r², count and the correlation's) of every candidate
    /// motion (12 floats each, abi::pack_candidates; layout of shaders/rigid/rigid_score.wgsl).
    fn rigid_scores(
        &self,
        params: &ScoreParams,
        images: &BoneImages<Self::Buffer<f32>>,
        candidates: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;
}
