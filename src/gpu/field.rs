//! Host side of shaders/warp_field.wgsl, shaders/compose.wgsl, shaders/fade_warp.wgsl and
//! shaders/invert_field.wgsl: the final field's kernels.

use super::kernel::{cover, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::{ComposeParams, FadeParams, InvertParams, RbfGradParams};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// warp_field bindings in the order the shader declares them.
pub const WARP_BINDINGS: &[Binding] = &[Uniform, Read, ReadWrite];
/// compose bindings.
pub const COMPOSE_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];
/// fade_warp bindings.
pub const FADE_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];
/// invert_field bindings.
pub const INVERT_BINDINGS: &[Binding] = &[Uniform, Read, ReadWrite, ReadWrite];

impl GpuBackend {
    /// The lattice interpolated at every voxel (3 floats per voxel).
    pub fn record_warp_field(
        &self,
        params: &RbfGradParams,
        lattice: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("warp field", 3 * params.voxels())?;
        self.record(
            &self.kernels.warp_field,
            params,
            &[lattice.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// u = R + u0 ∘ (id + R) (3 floats per voxel).
    pub fn record_compose(
        &self,
        params: &ComposeParams,
        warp: &GpuBuffer<f32>,
        initial: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("total field", 3 * params.voxels())?;
        self.record(
            &self.kernels.compose,
            params,
            &[warp.raw(), initial.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// The warp held off the bones (3 floats per voxel).
    pub fn record_fade_warp(
        &self,
        params: &FadeParams,
        warp: &GpuBuffer<f32>,
        distance: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("faded warp", 3 * params.voxels())?;
        self.record(
            &self.kernels.fade_warp,
            params,
            &[warp.raw(), distance.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// The field's inverse on the output grid (3 floats per voxel) and its residual (1 float).
    pub fn record_invert_field(
        &self,
        params: &InvertParams,
        field: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let out = self.output_buffer("inverse field", 3 * params.voxels())?;
        let residual = self.output_buffer("inverse residual", params.voxels())?;
        self.record(
            &self.kernels.invert_field,
            params,
            &[field.raw(), out.raw(), residual.raw()],
            cover(params.out_dims, 4),
        )?;
        Ok((out, residual))
    }
}
