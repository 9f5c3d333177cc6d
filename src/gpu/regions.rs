//! Host side of the regions family (shaders/regions/): distance maps and region moments, their
//! bindings, their compiled pipelines and the family's trait.

use super::context::GpuContext;
use super::kernel::{groups, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::{EdtParams, MomentsParams};
use crate::backend::regions::Regions;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("edt", &[Uniform, Read, ReadWrite]),
    ("moments", &[Uniform, Read, ReadWrite]),
];

/// The family's compiled kernels.
pub struct RegionsKernels {
    edt: Kernel,
    moments: Kernel,
}

impl RegionsKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(RegionsKernels {
            edt: compile(ctx, "edt")?,
            moments: compile(ctx, "moments")?,
        })
    }
}

impl Regions for GpuBackend {
    /// One axis's pass of the distance maps, one invocation per line.
    fn edt(&self, params: &EdtParams, input: &GpuBuffer<f32>) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("distance maps", params.values())?;
        let [a, b] = params.lines();
        self.record(
            &self.kernels.regions.edt,
            params,
            &[input.raw(), out.raw()],
            [groups(a, 8), groups(b, 8), params.volumes],
        )?;
        Ok(out)
    }

    /// Count and position sums per chunk.
    fn moments(&self, params: &MomentsParams, values: &GpuBuffer<f32>) -> Result<GpuBuffer<f64>> {
        let out = self.output_buffer("region moments", 4 * params.chunks())?;
        self.record(
            &self.kernels.regions.moments,
            params,
            &[values.raw(), out.raw()],
            [groups(params.chunks(), 64), 1, 1],
        )?;
        Ok(out)
    }
}
