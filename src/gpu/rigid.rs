//! Host side of the rigid family (shaders/rigid/): whole levels bound at once, per-column
//! partial results left on the device for sum_partials; the bindings, the compiled pipelines
//! and the family's trait.

use super::context::GpuContext;
use super::kernel::{groups, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::{RigidParams, ScoreParams, RIGID_SUMS, SCORE_SUMS};
use crate::backend::rigid::{BoneImages, Rigid};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("rigid_gn", &[Uniform, Read, Read, Read, ReadWrite]),
    ("rigid_score", &[Uniform, Read, Read, Read, Read, ReadWrite]),
];

/// The family's compiled kernels.
pub struct RigidKernels {
    rigid_gn: Kernel,
    rigid_score: Kernel,
}

impl RigidKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(RigidKernels {
            rigid_gn: compile(ctx, "rigid_gn")?,
            rigid_score: compile(ctx, "rigid_score")?,
        })
    }
}

impl Rigid for GpuBackend {
    /// Gauss-Newton column sums.
    fn rigid_sums(
        &self,
        params: &RigidParams,
        images: &BoneImages<GpuBuffer<f32>>,
    ) -> Result<GpuBuffer<f32>> {
        let partial = self.output_buffer("rigid column sums", params.columns() * RIGID_SUMS)?;
        self.record(
            &self.kernels.rigid.rigid_gn,
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
    fn rigid_scores(
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
            &self.kernels.rigid.rigid_score,
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
