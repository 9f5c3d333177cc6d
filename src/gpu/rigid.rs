//! Host side of shaders/rigid_gn.wgsl and shaders/rigid_score.wgsl: whole levels bound at once,
//! per-column partial results left on the device for sum_partials.

use super::kernel::{groups, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::{RigidParams, ScoreParams, RIGID_SUMS, SCORE_SUMS};
use crate::backend::BoneImages;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// rigid_gn bindings in the order the shader declares them.
pub const GN_BINDINGS: &[Binding] = &[Uniform, Read, Read, Read, ReadWrite];

/// rigid_score bindings in the order the shader declares them.
pub const SCORE_BINDINGS: &[Binding] = &[Uniform, Read, Read, Read, Read, ReadWrite];

impl GpuBackend {
    /// Gauss-Newton column sums.
    pub fn record_rigid_sums(
        &self,
        params: &RigidParams,
        images: &BoneImages<GpuBuffer<f32>>,
    ) -> Result<GpuBuffer<f32>> {
        let partial = self.output_buffer("rigid column sums", params.columns() * RIGID_SUMS)?;
        self.record(
            &self.kernels.rigid_gn,
            params,
            &[
                images.source.raw(),
                images.mask.raw(),
                images.target.raw(),
                partial.raw(),
            ],
            [groups(params.dims[0] as usize, 64), params.dims[2], 1],
        )?;
        Ok(partial)
    }

    /// Candidate scores per column.
    pub fn record_rigid_scores(
        &self,
        params: &ScoreParams,
        images: &BoneImages<GpuBuffer<f32>>,
        candidates: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let count = params.candidates();
        let partial = self.output_buffer(
            "candidate column scores",
            params.columns() * count * SCORE_SUMS,
        )?;
        self.record(
            &self.kernels.rigid_score,
            params,
            &[
                images.source.raw(),
                images.mask.raw(),
                images.target.raw(),
                candidates.raw(),
                partial.raw(),
            ],
            [
                groups(params.dims[0] as usize, 64),
                params.dims[2],
                count as u32,
            ],
        )?;
        Ok(partial)
    }
}
