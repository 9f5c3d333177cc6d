//! Sampling images: through a displacement field, the field's coverage of the source, and
//! pyramid levels (shaders/sampling/, abi::sampling, cpu::sampling, gpu::sampling).

use super::{Core, DeviceImage};
use crate::abi::{Interpolation, PyramidParams, ResampleParams};
use crate::error::Result;
use crate::volume::{Field, Grid, Image, Volume};

/// Kernels that read an image at other points than its voxel centres.
pub trait Sampling: Core {
    /// `source` sampled at x + u(x) for every voxel x of the target grid (`field`: u, 3 floats
    /// per voxel), trilinear or nearest; the background where that point is outside the
    /// source (`params`).
    fn resample(
        &self,
        params: &ResampleParams,
        source: &Self::Buffer<f32>,
        field: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// 1 where x + u(x) lies inside the source's field of view (sample.wgsl's rule) and x in
    /// `mask` (> 0), else 0, for every voxel x of the target grid (`params` as for a resample).
    fn coverage(
        &self,
        params: &ResampleParams,
        field: &Self::Buffer<f32>,
        mask: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// One pyramid step: a level smoothed and decimated (see pyramid::next_level_grid) as
    /// `params` says.
    fn pyramid_level(
        &self,
        params: &PyramidParams,
        input: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;
}

/// `image` sampled on `grid` without any displacement (0 outside): the unregistered source
/// seen on the target's grid (trilinear), a mask or a label map on another level (nearest).
pub fn resample_onto<B: Sampling>(
    backend: &B,
    image: &DeviceImage<B>,
    grid: &Grid,
    interpolation: Interpolation,
) -> Result<DeviceImage<B>> {
    let params = ResampleParams::new(&image.grid, grid, 0.0, interpolation);
    let still = backend.zeros("zero displacement", 3 * grid.len())?;
    Ok(DeviceImage {
        data: backend.resample(&params, &image.data, &still)?,
        grid: grid.clone(),
    })
}

/// `source` resampled through `field` (on the target grid) for a command working on volumes
/// from disk: both go where the backend computes, the result comes back.
pub fn resample_volume<B: Sampling>(
    backend: &B,
    source: &Volume,
    field: &Field,
    background: f32,
    interpolation: Interpolation,
) -> Result<Volume> {
    let params = ResampleParams::new(&source.grid, &field.grid, background, interpolation);
    let image = DeviceImage::upload(backend, "volume to resample", source.clone())?;
    let field_on_device = DeviceImage::upload_field(backend, "displacement field", field.clone())?;
    Image::from_data(
        field.grid.clone(),
        backend.download_one(&backend.resample(&params, &image.data, &field_on_device.data)?)?,
    )
}
