//! Host side of shaders/local_moments.wgsl, shaders/lncc.wgsl, shaders/lncc_terms.wgsl and
//! shaders/lncc_gradient.wgsl: the local correlation of two images, and its cost and gradient
//! through a warp.

use super::kernel::{cover, groups, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::{LnccParams, LnccTermsParams, LocalMomentsParams, RbfGradParams};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// local_moments bindings in the order the shader declares them.
pub const MOMENTS_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];
/// lncc bindings.
pub const LNCC_BINDINGS: &[Binding] = &[Uniform, Read, ReadWrite];
/// lncc_terms bindings.
pub const TERMS_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite, ReadWrite];
/// lncc_gradient bindings.
pub const GRADIENT_BINDINGS: &[Binding] = &[Uniform, Read, Read, Read, Read, ReadWrite];

impl GpuBackend {
    /// One axis's pass of the box sums.
    pub fn record_local_moments(
        &self,
        params: &LocalMomentsParams,
        input: &GpuBuffer<f32>,
        other: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("local moments", params.values())?;
        self.record(
            &self.kernels.local_moments,
            params,
            &[input.raw(), other.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// 2 floats per chunk: Σ ρ² and the voxels counted.
    pub fn record_lncc(
        &self,
        params: &LnccParams,
        sums: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("local correlation sums", 2 * params.chunks())?;
        self.record(
            &self.kernels.lncc,
            params,
            &[sums.raw(), out.raw()],
            [groups(params.chunks(), 64), 1, 1],
        )?;
        Ok(out)
    }

    /// The cost's terms (5 floats per voxel) and K Σ c (1 − ρ²) per row of x.
    pub fn record_lncc_terms(
        &self,
        params: &LnccTermsParams,
        sums: &GpuBuffer<f32>,
        covered: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let terms = self.output_buffer("local correlation terms", params.values())?;
        let rows = self.output_buffer("per-row local correlation cost", params.rows())?;
        let [_, ny, nz, _] = params.dims.map(|n| n as usize);
        self.record(
            &self.kernels.lncc_terms,
            params,
            &[sums.raw(), covered.raw(), terms.raw(), rows.raw()],
            [groups(ny, 8), groups(nz, 8), 1],
        )?;
        Ok((terms, rows))
    }

    /// The per-voxel gradient of the local-correlation cost through the warp.
    pub fn record_lncc_gradient(
        &self,
        params: &RbfGradParams,
        lattice: &GpuBuffer<f32>,
        [moving, fixed]: [&GpuBuffer<f32>; 2],
        summed: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let [_, ny, nz, _] = params.dims.map(|n| n as usize);
        let gradient = self.output_buffer("per-voxel cost gradient", 3 * params.voxels())?;
        self.record(
            &self.kernels.lncc_gradient,
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
