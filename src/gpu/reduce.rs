//! Host side of the reduce family (shaders/reduce/): chunked sums in f64 and the passes adding
//! partial results, their bindings, their compiled pipelines and the family's trait.

use super::context::GpuContext;
use super::kernel::{groups, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::{ListParams, PartialsParams, SumParams};
use crate::backend::reduce::Reduce;
use crate::backend::Element;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("sum_chunks", &[Uniform, Read, ReadWrite]),
    ("sum_partials", &[Uniform, Read, ReadWrite]),
    ("sum_partials_f32", &[Uniform, Read, ReadWrite]),
    ("list_flagged", &[Uniform, Read, Read, ReadWrite, ReadWrite]),
];

/// The family's compiled kernels.
pub struct ReduceKernels {
    sum_chunks: Kernel,
    /// shaders/reduce/sum_partials.wgsl over f64 partials.
    sum_partials: Kernel,
    /// shaders/reduce/sum_partials.wgsl over f32 partials.
    sum_partials_f32: Kernel,
    list_flagged: Kernel,
}

impl ReduceKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(ReduceKernels {
            sum_chunks: compile(ctx, "sum_chunks")?,
            sum_partials: compile(ctx, "sum_partials")?,
            sum_partials_f32: compile(ctx, "sum_partials_f32")?,
            list_flagged: compile(ctx, "list_flagged")?,
        })
    }
}

impl Reduce for GpuBackend {
    /// Pass after pass until one group is left.
    fn sum_partials<T: Element>(
        &self,
        partials: &GpuBuffer<T>,
        values: usize,
    ) -> Result<GpuBuffer<f64>> {
        let kernels = &self.kernels.reduce;
        let mut sums: Option<GpuBuffer<f64>> = None;
        for pass in PartialsParams::passes(values, partials.len() / values.max(1)) {
            let (kernel, input) = match &sums {
                None if T::WGSL == "f32" => (&kernels.sum_partials_f32, partials.raw()),
                None => (&kernels.sum_partials, partials.raw()),
                Some(earlier) => (&kernels.sum_partials, earlier.raw()),
            };
            let out = self.output_buffer("summed partials", pass.groups() * values)?;
            self.record(
                kernel,
                &pass,
                &[input, out.raw()],
                [groups(values, 64), pass.groups() as u32, 1],
            )?;
            sums = Some(out);
        }
        Ok(sums.expect("at least one pass"))
    }

    /// One f64 sum per chunk.
    fn sum_chunks(&self, params: &SumParams, values: &GpuBuffer<f32>) -> Result<GpuBuffer<f64>> {
        let sums = self.output_buffer("partial sums", params.chunks())?;
        self.record(
            &self.kernels.reduce.sum_chunks,
            params,
            &[values.raw(), sums.raw()],
            [groups(params.chunks(), 64), 1, 1],
        )?;
        Ok(sums)
    }

    /// One invocation per chunk, each writing from its offset.
    fn list_flagged(
        &self,
        params: &ListParams,
        flags: &GpuBuffer<f32>,
        offsets: &GpuBuffer<u32>,
        listed: usize,
    ) -> Result<(GpuBuffer<u32>, GpuBuffer<f32>)> {
        let indices = self.output_buffer("flagged voxels", listed)?;
        let values = self.output_buffer("flagged values", listed)?;
        self.record(
            &self.kernels.reduce.list_flagged,
            params,
            &[flags.raw(), offsets.raw(), indices.raw(), values.raw()],
            [groups(params.chunks(), 64), 1, 1],
        )?;
        Ok((indices, values))
    }
}
