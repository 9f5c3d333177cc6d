//! CPU twins of the regions family's kernels (shaders/regions/).

mod edt;
mod moments;

use super::{filled, CpuBackend};
use crate::abi::{EdtParams, MomentsParams};
use crate::backend::regions::Regions;
use crate::error::Result;
use std::sync::Arc;

impl Regions for CpuBackend {
    fn edt(&self, params: &EdtParams, input: &Arc<Vec<f32>>) -> Result<Arc<Vec<f32>>> {
        filled(params.values(), |out| edt::edt(params, input, out))
    }

    fn moments(&self, params: &MomentsParams, values: &Arc<Vec<f32>>) -> Result<Arc<Vec<f64>>> {
        filled(4 * params.chunks(), |out| {
            moments::moments(params, values, out)
        })
    }
}
