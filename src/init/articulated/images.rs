//! The images the initialisation and the pipeline share where the backend computes: the
//! pair, uploaded once, and the initial field with what it moves.

use crate::abi::Interpolation;
use crate::backend::{resample_onto, Backend, DeviceImage};
use crate::error::Result;
use crate::volume::{Field, Image, Labels, Volume};

/// The initialisation's images, where the backend computes.
pub struct InitialImages<B: Backend> {
    /// u0: target point p → source point p + u0(p), world RAS mm (3 values per voxel).
    pub field: DeviceImage<B>,
    /// The blend's inversion residual per target voxel (mm).
    pub residual: DeviceImage<B>,
    /// The source moved by the initial field, on the target grid.
    pub initialised: DeviceImage<B>,
}

impl<B: Backend> InitialImages<B> {
    /// The initial images when the articulated initialisation is skipped: no displacement,
    /// and the source just resampled onto the target's grid.
    pub fn identity(backend: &B, pair: &PairImages<B>) -> Result<Self> {
        let grid = &pair.target.grid;
        let zeros = |what, per_voxel| -> Result<DeviceImage<B>> {
            Ok(DeviceImage {
                data: backend.zeros(what, per_voxel * grid.len())?,
                grid: grid.clone(),
            })
        };
        Ok(InitialImages {
            field: zeros("zero displacement", 3)?,
            residual: zeros("zero residual", 1)?,
            initialised: resample_onto(backend, &pair.source, grid, Interpolation::Linear)?,
        })
    }
}

/// The initialisation's images on the host: what `posereg init` writes.
pub struct InitialVolumes {
    /// u0: target point p → source point p + u0(p), world RAS mm.
    pub field: Field,
    /// The blend's inversion residual per target voxel (mm).
    pub residual: Volume,
    /// The source moved by the initial field, on the target grid.
    pub initialised: Volume,
}

impl<B: Backend> InitialImages<B> {
    /// Brings the three images back (one wait).
    pub fn download(&self, backend: &B) -> Result<InitialVolumes> {
        let mut out = backend.download(&[
            &self.field.data,
            &self.residual.data,
            &self.initialised.data,
        ])?;
        let grid = &self.field.grid;
        let (initialised, residual) =
            (out.pop().unwrap_or_default(), out.pop().unwrap_or_default());
        let field = out.pop().unwrap_or_default();
        Ok(InitialVolumes {
            field: Image::from_data(grid.clone(), bytemuck::cast_vec(field))?,
            residual: Image::from_data(grid.clone(), residual)?,
            initialised: Image::from_data(grid.clone(), initialised)?,
        })
    }
}

/// A pair's images where the backend computes, uploaded once for a whole registration.
pub struct PairImages<B: Backend> {
    /// The source (straight) scan.
    pub source: DeviceImage<B>,
    /// Its bone labels, codes as f32.
    pub labels: DeviceImage<B>,
    /// The target (bent) scan.
    pub target: DeviceImage<B>,
}

impl<B: Backend> PairImages<B> {
    /// Uploads the three images.
    pub fn upload(backend: &B, source: &Volume, labels: &Labels, target: &Volume) -> Result<Self> {
        Ok(PairImages {
            source: DeviceImage::upload(backend, "source", source.clone())?,
            labels: DeviceImage::upload_labels(backend, labels)?,
            target: DeviceImage::upload(backend, "target", target.clone())?,
        })
    }
}
