//! CPU twins of the dense stage's kernels (shaders/dense/).

mod dense_force;
mod field_combine;
mod gauss_axis;
mod norm_max;

use super::{filled, filled_pair, CpuBackend};
use crate::abi::dense::{CombineParams, ForceParams, GaussParams, NormParams};
use crate::backend::dense::{Dense, ForceImages};
use crate::error::Result;
use std::sync::Arc;

impl Dense for CpuBackend {
    fn gauss_axis(&self, params: &GaussParams, input: &Arc<Vec<f32>>) -> Result<Arc<Vec<f32>>> {
        filled(params.values(), |out| {
            gauss_axis::gauss_axis(params, input, out)
        })
    }

    fn dense_force(
        &self,
        params: &ForceParams,
        images: &ForceImages<Arc<Vec<f32>>>,
    ) -> Result<(Arc<Vec<f32>>, Arc<Vec<f32>>)> {
        let images = ForceImages {
            moving: images.moving.as_slice(),
            fixed: images.fixed.as_slice(),
            covered: images.covered.as_slice(),
            sums: images.sums.as_slice(),
        };
        let voxels = params.voxels();
        filled_pair([3 * voxels, voxels], |force, cost| {
            dense_force::dense_force(params, &images, force, cost)
        })
    }

    fn norm_max(&self, params: &NormParams, field: &Arc<Vec<f32>>) -> Result<Arc<Vec<f32>>> {
        filled(params.chunks as usize, |out| {
            norm_max::norm_max(params, field, out)
        })
    }

    fn field_combine(
        &self,
        params: &CombineParams,
        a: &Arc<Vec<f32>>,
        b: &Arc<Vec<f32>>,
        distance: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(3 * params.voxels(), |out| {
            field_combine::field_combine(params, a, b, distance, out)
        })
    }
}
