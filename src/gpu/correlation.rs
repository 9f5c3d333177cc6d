//! Host side of the correlation family (shaders/correlation/): the local correlation of two
//! images, and its cost and gradient through a warp; their bindings, their compiled pipelines
//! and the family's trait.

use super::context::GpuContext;
use super::kernel::{cover, groups, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::{LnccParams, LnccTermsParams, LocalMomentsParams, RbfGradParams};
use crate::backend::correlation::Correlation;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("local_moments", &[Uniform, Read, Read, ReadWrite]),
    ("lncc", &[Uniform, Read, ReadWrite]),
    ("lncc_terms", &[Uniform, Read, Read, ReadWrite, ReadWrite]),
    (
        "lncc_gradient",
        &[Uniform, Read, Read, Read, Read, ReadWrite],
    ),
];

/// The family's compiled kernels.
pub struct CorrelationKernels {
    local_moments: Kernel,
    lncc: Kernel,
    lncc_terms: Kernel,
    lncc_gradient: Kernel,
}

impl CorrelationKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(CorrelationKernels {
            local_moments: compile(ctx, "local_moments")?,
            lncc: compile(ctx, "lncc")?,
            lncc_terms: compile(ctx, "lncc_terms")?,
            lncc_gradient: compile(ctx, "lncc_gradient")?,
        })
    }
}

impl Correlation for GpuBackend {
    /// One axis's pass of the box sums.
    fn local_moments(
        &self,
        params: &LocalMomentsParams,
        input: &GpuBuffer<f32>,
        other: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("local moments", params.values())?;
        self.record(
            &self.kernels.correlation.local_moments,
            params,
            &[input.raw(), other.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// 2 floats per chunk: Σ ρ² and the voxels counted.
    fn lncc(&self, params: &LnccParams, sums: &GpuBuffer<f32>) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("local correlation sums", 2 * params.chunks())?;
        self.record(
            &self.kernels.correlation.lncc,
            params,
            &[sums.raw(), out.raw()],
            [groups(params.chunks(), 64), 1, 1],
        )?;
        Ok(out)
    }

    /// The cost's terms (5 floats per voxel) and K Σ c (1 − ρ²) per row of x.
    fn lncc_terms(
        &self,
        params: &LnccTermsParams,
        sums: &GpuBuffer<f32>,
        covered: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let terms = self.output_buffer("local correlation terms", params.values())?;
        let rows = self.output_buffer("per-row local correlation cost", params.rows())?;
        let [_, ny, nz, _] = params.dims.map(|n| n as usize);
        self.record(
            &self.kernels.correlation.lncc_terms,
            params,
            &[sums.raw(), covered.raw(), terms.raw(), rows.raw()],
            [groups(ny, 8), groups(nz, 8), 1],
        )?;
        Ok((terms, rows))
    }

    /// The per-voxel gradient of the local-correlation cost through the warp.
    fn lncc_gradient(
        &self,
        params: &RbfGradParams,
        lattice: &GpuBuffer<f32>,
        moving: &GpuBuffer<f32>,
        fixed: &GpuBuffer<f32>,
        summed: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let [_, ny, nz, _] = params.dims.map(|n| n as usize);
        let gradient = self.output_buffer("per-voxel cost gradient", 3 * params.voxels())?;
        self.record(
            &self.kernels.correlation.lncc_gradient,
            params,
            &[
                lattice.raw(),
                moving.raw(),
                fixed.raw(),
                summed.raw(),
                gradient.raw(),
            ],
            [groups(ny, 8), groups(nz, 8), 1],
        )?;
        Ok(gradient)
    }
}
