//! Host side of the field family (shaders/field/): the final field's kernels (the warp on the
//! grid, its fade off the bones, composition and inversion), their bindings, their compiled
//! pipelines and the family's trait.

use super::context::GpuContext;
use super::kernel::{cover, groups, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::{
    ComposeParams, FadeParams, InvertParams, RbfGradParams, RoundTripParams, ROUND_TRIP_WIDTH,
};
use crate::backend::field::Fields;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("warp_field", &[Uniform, Read, ReadWrite]),
    ("compose", &[Uniform, Read, Read, ReadWrite]),
    ("fade_warp", &[Uniform, Read, Read, ReadWrite]),
    ("invert_field", &[Uniform, Read, ReadWrite, ReadWrite]),
    ("round_trip_stats", &[Uniform, Read, Read, ReadWrite]),
];

/// The family's compiled kernels.
pub struct FieldKernels {
    warp_field: Kernel,
    compose: Kernel,
    fade_warp: Kernel,
    invert_field: Kernel,
    round_trip_stats: Kernel,
}

impl FieldKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(FieldKernels {
            warp_field: compile(ctx, "warp_field")?,
            compose: compile(ctx, "compose")?,
            fade_warp: compile(ctx, "fade_warp")?,
            invert_field: compile(ctx, "invert_field")?,
            round_trip_stats: compile(ctx, "round_trip_stats")?,
        })
    }
}

impl Fields for GpuBackend {
    /// The lattice interpolated at every voxel (3 floats per voxel).
    fn warp_field(
        &self,
        params: &RbfGradParams,
        lattice: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("warp field", 3 * params.voxels())?;
        self.record(
            &self.kernels.field.warp_field,
            params,
            &[lattice.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// u = R + u0 ∘ (id + R) (3 floats per voxel).
    fn compose(
        &self,
        params: &ComposeParams,
        warp: &GpuBuffer<f32>,
        initial: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("total field", 3 * params.voxels())?;
        self.record(
            &self.kernels.field.compose,
            params,
            &[warp.raw(), initial.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// The warp held off the bones (3 floats per voxel).
    fn fade_warp(
        &self,
        params: &FadeParams,
        warp: &GpuBuffer<f32>,
        distance: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("faded warp", 3 * params.voxels())?;
        self.record(
            &self.kernels.field.fade_warp,
            params,
            &[warp.raw(), distance.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// The field's inverse on the output grid (3 floats per voxel) and its residual (1 float).
    fn invert_field(
        &self,
        params: &InvertParams,
        field: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let out = self.output_buffer("inverse field", 3 * params.voxels())?;
        let residual = self.output_buffer("inverse residual", params.voxels())?;
        self.record(
            &self.kernels.field.invert_field,
            params,
            &[field.raw(), out.raw(), residual.raw()],
            cover(params.out_dims, 4),
        )?;
        Ok((out, residual))
    }

    /// One invocation per chunk of source voxels.
    fn round_trip_stats(
        &self,
        params: &RoundTripParams,
        residual: &GpuBuffer<f32>,
        source: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f64>> {
        let stats =
            self.output_buffer("round-trip statistics", ROUND_TRIP_WIDTH * params.chunks())?;
        self.record(
            &self.kernels.field.round_trip_stats,
            params,
            &[residual.raw(), source.raw(), stats.raw()],
            [groups(params.chunks(), 64), 1, 1],
        )?;
        Ok(stats)
    }
}
