//! CPU twins of the field family's kernels (shaders/field/).

mod compose;
mod fade_warp;
mod invert_field;
mod round_trip_stats;
mod warp_field;

use super::{filled, filled_pair, CpuBackend};
use crate::abi::{
    ComposeParams, FadeParams, InvertParams, RbfGradParams, RoundTripParams, ROUND_TRIP_WIDTH,
};
use crate::backend::field::Fields;
use crate::error::Result;
use std::sync::Arc;

impl Fields for CpuBackend {
    fn warp_field(&self, params: &RbfGradParams, lattice: &Arc<Vec<f32>>) -> Result<Arc<Vec<f32>>> {
        filled(3 * params.voxels(), |out| {
            warp_field::warp_field(params, lattice, out)
        })
    }

    fn compose(
        &self,
        params: &ComposeParams,
        warp: &Arc<Vec<f32>>,
        initial: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(3 * params.voxels(), |out| {
            compose::compose(params, warp, initial, out)
        })
    }

    fn fade_warp(
        &self,
        params: &FadeParams,
        warp: &Arc<Vec<f32>>,
        distance: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(3 * params.voxels(), |out| {
            fade_warp::fade_warp(params, warp, distance, out)
        })
    }

    fn invert_field(
        &self,
        params: &InvertParams,
        field: &Arc<Vec<f32>>,
    ) -> Result<(Arc<Vec<f32>>, Arc<Vec<f32>>)> {
        filled_pair([3 * params.voxels(), params.voxels()], |out, residual| {
            invert_field::invert_field(params, field, out, residual);
        })
    }

    fn round_trip_stats(
        &self,
        params: &RoundTripParams,
        residual: &Arc<Vec<f32>>,
        source: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f64>>> {
        filled(ROUND_TRIP_WIDTH * params.chunks(), |out| {
            round_trip_stats::round_trip_stats(params, residual, source, out)
        })
    }
}
