//! Host side of the dense stage's kernels (shaders/dense/): their bindings, their compiled
//! pipelines and the family's trait.

use super::context::GpuContext;
use super::kernel::{cover, groups, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::dense::{CombineParams, ForceParams, GaussParams, NormParams};
use crate::backend::dense::{Dense, ForceImages};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("gauss_axis", &[Uniform, Read, ReadWrite]),
    (
        "dense_force",
        &[Uniform, Read, Read, Read, Read, ReadWrite, ReadWrite],
    ),
    ("norm_max", &[Uniform, Read, ReadWrite]),
    ("field_combine", &[Uniform, Read, Read, Read, ReadWrite]),
];

/// The family's compiled kernels.
pub struct DenseKernels {
    gauss_axis: Kernel,
    dense_force: Kernel,
    norm_max: Kernel,
    field_combine: Kernel,
}

impl DenseKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(DenseKernels {
            gauss_axis: compile(ctx, "gauss_axis")?,
            dense_force: compile(ctx, "dense_force")?,
            norm_max: compile(ctx, "norm_max")?,
            field_combine: compile(ctx, "field_combine")?,
        })
    }
}

impl Dense for GpuBackend {
    fn gauss_axis(&self, params: &GaussParams, input: &GpuBuffer<f32>) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("smoothed field", params.values())?;
        let dims = [params.nx, params.ny, params.nz, 0];
        let kernel = &self.kernels.dense.gauss_axis;
        self.record(kernel, params, &[input.raw(), out.raw()], cover(dims, 4))?;
        Ok(out)
    }

    fn dense_force(
        &self,
        params: &ForceParams,
        images: &ForceImages<GpuBuffer<f32>>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let force = self.output_buffer("dense force", 3 * params.voxels())?;
        let cost = self.output_buffer("dense cost", params.voxels())?;
        let bound = [
            images.moving.raw(),
            images.fixed.raw(),
            images.covered.raw(),
            images.sums.raw(),
            force.raw(),
            cost.raw(),
        ];
        let dims = [params.nx, params.ny, params.nz, 0];
        self.record(
            &self.kernels.dense.dense_force,
            params,
            &bound,
            cover(dims, 4),
        )?;
        Ok((force, cost))
    }

    fn norm_max(&self, params: &NormParams, field: &GpuBuffer<f32>) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("largest vectors", params.chunks as usize)?;
        let shape = [groups(params.chunks as usize, 64), 1, 1];
        self.record(
            &self.kernels.dense.norm_max,
            params,
            &[field.raw(), out.raw()],
            shape,
        )?;
        Ok(out)
    }

    fn field_combine(
        &self,
        params: &CombineParams,
        a: &GpuBuffer<f32>,
        b: &GpuBuffer<f32>,
        distance: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("combined field", 3 * params.voxels())?;
        let bound = [a.raw(), b.raw(), distance.raw(), out.raw()];
        let dims = [params.nx, params.ny, params.nz, 0];
        self.record(
            &self.kernels.dense.field_combine,
            params,
            &bound,
            cover(dims, 4),
        )?;
        Ok(out)
    }
}
