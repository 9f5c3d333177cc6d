//! Reductions: chunked sums in f64 and the passes adding partial results.

use super::*;

/// Values per chunk of sum_chunks.
pub const SUM_CHUNK: usize = 1024;

/// Keep in sync with `SumParams` in shaders/reduce/sum_chunks.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SumParams {
    /// Values, values per chunk, chunks, unused.
    pub counts: [u32; 4],
    /// Shift subtracted from each value before the power.
    pub shift: f32,
    /// The power (1 or 2; 0 counts the values above the shift).
    pub power: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 2],
}

impl SumParams {
    /// Sums of `values` values in chunks of [`SUM_CHUNK`].
    pub fn new(values: usize) -> Self {
        SumParams {
            counts: chunking(values, SUM_CHUNK, 0),
            shift: 0.0,
            power: 1,
            pad: [0; 2],
        }
    }

    /// Sums of the squares of `values` values minus `shift`.
    pub fn squares_about(values: usize, shift: f32) -> Self {
        let mut p = SumParams::new(values);
        p.power = 2;
        p.shift = shift;
        p
    }

    /// Counts of the values above `shift` among `values` values, per chunk.
    pub fn count_above(values: usize, shift: f32) -> Self {
        let mut p = SumParams::new(values);
        p.power = 0;
        p.shift = shift;
        p
    }

    /// Values summed.
    pub fn values(&self) -> usize {
        self.counts[0] as usize
    }

    /// Chunks, hence sums.
    pub fn chunks(&self) -> usize {
        self.counts[2] as usize
    }
}

/// Keep in sync with `ListParams` in shaders/reduce/list_flagged.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct ListParams {
    /// Values, values per chunk ([`SUM_CHUNK`], as sum_chunks counts them), chunks, unused.
    pub counts: [u32; 4],
}

impl ListParams {
    /// Lists the flagged values among `values` values, chunk by chunk.
    pub fn new(values: usize) -> Self {
        ListParams {
            counts: chunking(values, SUM_CHUNK, 0),
        }
    }

    /// Chunks, hence offsets.
    pub fn chunks(&self) -> usize {
        self.counts[2] as usize
    }
}

/// Keep in sync with `PartialsParams` in shaders/reduce/sum_partials.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct PartialsParams {
    /// Values per chunk, chunks, chunks per group, unused.
    pub counts: [u32; 4],
}

/// Most chunks one sum_partials invocation adds.
pub const PARTIALS_GROUP: usize = 1024;

impl PartialsParams {
    /// The passes that add `chunks` partial results of `values` values each down to one: each
    /// adds groups of up to [`PARTIALS_GROUP`] chunks, and the next adds its groups.
    pub fn passes(values: usize, chunks: usize) -> Vec<PartialsParams> {
        let mut passes = Vec::new();
        let mut chunks = chunks.max(1);
        loop {
            let group = chunks.min(PARTIALS_GROUP);
            passes.push(PartialsParams {
                counts: [values as u32, chunks as u32, group as u32, 0],
            });
            if group == chunks {
                return passes;
            }
            chunks = chunks.div_ceil(group);
        }
    }

    /// Values per chunk.
    pub fn values(&self) -> usize {
        self.counts[0] as usize
    }

    /// Groups this pass writes (values each).
    pub fn groups(&self) -> usize {
        (self.counts[1] as usize).div_ceil(self.counts[2].max(1) as usize)
    }
}
