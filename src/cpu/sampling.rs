//! CPU twins of the sampling family's kernels (shaders/sampling/).

mod coverage;
mod pyramid;
mod resample;

use super::{filled, CpuBackend};
use crate::abi::{PyramidParams, ResampleParams};
use crate::backend::sampling::Sampling;
use crate::error::Result;
use std::sync::Arc;

impl Sampling for CpuBackend {
    fn resample(
        &self,
        params: &ResampleParams,
        source: &Arc<Vec<f32>>,
        field: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            resample::resample(params, source, field, out)
        })
    }

    fn coverage(
        &self,
        params: &ResampleParams,
        field: &Arc<Vec<f32>>,
        mask: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            coverage::coverage(params, field, mask, out)
        })
    }

    fn pyramid_level(
        &self,
        params: &PyramidParams,
        input: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.output_len(), |out| {
            pyramid::pyramid(params, input, out)
        })
    }
}
