//! The dense stage's kernel family (shaders/dense/, abi::dense, cpu::dense, gpu::dense).

use super::Core;
use crate::abi::dense::{CombineParams, ForceParams, GaussParams, NormParams};
use crate::error::Result;
use crate::volume::Grid;

/// The images one evaluation of the dense force compares, on the target grid.
pub struct ForceImages<'a, T: ?Sized> {
    /// W: the source seen through the whole field.
    pub moving: &'a T,
    /// F: the target.
    pub fixed: &'a T,
    /// c: 1 where the field's point lies inside the source (the coverage kernel's).
    pub covered: &'a T,
    /// LNCC: the box sums of (W, F) (`local_moments`' last pass); SSD: unused (any buffer).
    pub sums: &'a T,
}

/// Kernels of the dense refinement: smoothing, the force, the update's size and the velocity's
/// update. The stage also composes, resamples and box-sums with the other families' kernels.
pub trait Dense: Core {
    /// One axis's pass of a separable Gaussian smoothing (`params`) of `input`
    /// (`params.components` floats per voxel).
    fn gauss_axis(
        &self,
        params: &GaussParams,
        input: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// The force (3 floats per voxel, world mm) and the cost (1 float per voxel) of the image
    /// term `params` names (shaders/dense/dense_force.wgsl).
    fn dense_force(
        &self,
        params: &ForceParams,
        images: &ForceImages<Self::Buffer<f32>>,
    ) -> Result<(Self::Buffer<f32>, Self::Buffer<f32>)>;

    /// The largest vector length of `field` (3 floats per voxel) per chunk of
    /// abi::dense::NORM_CHUNK vectors.
    fn norm_max(&self, params: &NormParams, field: &Self::Buffer<f32>)
        -> Result<Self::Buffer<f32>>;

    /// fade · (a_scale · a + b_scale · b), fields of 3 floats per voxel, faded to zero on the
    /// bones over the margin when `params` asks (`distance`: mm to the nearest bone; unused
    /// otherwise).
    fn field_combine(
        &self,
        params: &CombineParams,
        a: &Self::Buffer<f32>,
        b: &Self::Buffer<f32>,
        distance: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;
}

/// `input` (`components` floats per voxel on `grid`) smoothed by a Gaussian of `sigma` voxels:
/// the three passes of [`Dense::gauss_axis`]; 0 returns `input` as it is.
pub fn smooth<B: Dense>(
    backend: &B,
    grid: &Grid,
    components: usize,
    sigma: f64,
    input: &B::Buffer<f32>,
) -> Result<B::Buffer<f32>> {
    if sigma <= 0.0 {
        return Ok(input.clone());
    }
    let [x, y, z] = GaussParams::passes(grid, components, sigma);
    let along_x = backend.gauss_axis(&x, input)?;
    let along_y = backend.gauss_axis(&y, &along_x)?;
    backend.gauss_axis(&z, &along_y)
}

/// The largest vector length of each of `fields` (3 floats per voxel on `grid`): the chunks'
/// maxima come back, with one wait, and the largest of each is taken here.
pub fn largest_vectors<B: Dense>(
    backend: &B,
    grid: &Grid,
    fields: &[&B::Buffer<f32>],
) -> Result<Vec<f32>> {
    let params = NormParams::new(grid);
    let maxima = fields
        .iter()
        .map(|field| backend.norm_max(&params, field))
        .collect::<Result<Vec<_>>>()?;
    let maxima: Vec<&B::Buffer<f32>> = maxima.iter().collect();
    Ok(backend
        .download(&maxima)?
        .into_iter()
        .map(|chunks| chunks.into_iter().fold(0.0, f32::max))
        .collect())
}
