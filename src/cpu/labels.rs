//! CPU twins of the label family's kernels (shaders/labels/; their lookups, labels.wgsl and
//! bone_lookup.wgsl, are twinned in crate::sample).

mod bone_at_source;
mod label_index;
mod region_surface;

use super::{filled, CpuBackend};
use crate::abi::{BoneLookupParams, LabelParams, SurfaceParams};
use crate::backend::labels::LabelMaps;
use crate::error::Result;
use std::sync::Arc;

impl LabelMaps for CpuBackend {
    fn label_index(&self, params: &LabelParams, labels: &Arc<Vec<f32>>) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            label_index::label_index(params, labels, out)
        })
    }

    fn bone_at_source(
        &self,
        params: &BoneLookupParams,
        field: &Arc<Vec<f32>>,
        residual: &Arc<Vec<f32>>,
        labels: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            bone_at_source::bone_at_source(params, field, residual, labels, out)
        })
    }

    fn region_surface(
        &self,
        params: &SurfaceParams,
        regions: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            region_surface::region_surface(params, regions, out)
        })
    }
}
