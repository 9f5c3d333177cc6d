//! Label maps: codes to indices, and the bone a field carries a point into (shaders/labels/,
//! abi::labels, cpu::labels, gpu::labels).

use super::Core;
use crate::abi::{BoneLookupParams, LabelParams, SurfaceParams};
use crate::error::Result;

/// Kernels that read label maps.
pub trait LabelMaps: Core {
    /// Per voxel of a label map: 1 + the position of its label among `params`' codes, 0 for
    /// any other label.
    fn label_index(
        &self,
        params: &LabelParams,
        labels: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// Per target voxel x: 1 + the position among `params`' bone codes of the source label
    /// (nearest voxel) at x + u(x), where the voxel's `residual` is within `params`' limit;
    /// 0 elsewhere.
    fn bone_at_source(
        &self,
        params: &BoneLookupParams,
        field: &Self::Buffer<f32>,
        residual: &Self::Buffer<f32>,
        labels: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// Per voxel of a region map (a region's number per voxel, 0 for none): its number where
    /// one of its six neighbours inside the grid has another, else 0 (each region's boundary).
    fn region_surface(
        &self,
        params: &SurfaceParams,
        regions: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;
}
