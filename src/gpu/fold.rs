//! Host side of shaders/fold_stats.wgsl, shaders/mark_at_most.wgsl, shaders/dilate.wgsl and
//! shaders/fold_smooth.wgsl.

use super::kernel::{cover, groups, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::{BoneLookupParams, DilateParams, ThresholdParams, FOLD_STATS_WIDTH};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// fold_stats, mark_at_most and dilate bindings in the order the shaders declare them.
pub const FOLD_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];
/// fold_smooth bindings.
pub const SMOOTH_BINDINGS: &[Binding] = &[Uniform, Read, Read, Read, ReadWrite];

impl GpuBackend {
    /// FOLD_STATS_WIDTH floats of fold statistics per chunk.
    pub fn record_fold_stats(
        &self,
        params: &ThresholdParams,
        det: &GpuBuffer<f32>,
        held: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let stats = self.output_buffer("fold statistics", FOLD_STATS_WIDTH * params.chunks())?;
        self.record(
            &self.kernels.fold_stats,
            params,
            &[det.raw(), held.raw(), stats.raw()],
            [groups(params.chunks(), 64), 1, 1],
        )?;
        Ok(stats)
    }

    /// The voxels not held at or below the threshold.
    pub fn record_mark_at_most(
        &self,
        params: &ThresholdParams,
        value: &GpuBuffer<f32>,
        held: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let mark = self.output_buffer("marked voxels", params.voxels())?;
        self.record(
            &self.kernels.mark_at_most,
            params,
            &[value.raw(), held.raw(), mark.raw()],
            cover(params.dims, 4),
        )?;
        Ok(mark)
    }

    /// One axis of a box dilation.
    pub fn record_dilate(
        &self,
        params: &DilateParams,
        mask: &GpuBuffer<f32>,
        held: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("dilated mask", params.voxels())?;
        self.record(
            &self.kernels.dilate,
            params,
            &[mask.raw(), held.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// One smoothing sweep over the region.
    pub fn record_fold_smooth(
        &self,
        params: &BoneLookupParams,
        field: &GpuBuffer<f32>,
        region: &GpuBuffer<f32>,
        labels: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("smoothed field", 3 * params.voxels())?;
        self.record(
            &self.kernels.fold_smooth,
            params,
            &[field.raw(), region.raw(), labels.raw(), out.raw()],
            cover(params.geometry.target_dims, 4),
        )?;
        Ok(out)
    }
}
