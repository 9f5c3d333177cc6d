//! The inverse of a registration's field: where each source point lies in the target, so that
//! images and labels drawn on the target can be brought back onto the source
//! (`inverse_field.nii.gz`, `posereg apply --inverse`), with how well it undoes the field.

use crate::abi::{InvertParams, RoundTripParams, ROUND_TRIP_WIDTH};
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use crate::volume::Grid;

/// How closely the inverse undoes the field: for a source point y with inverse w(y) and
/// z = y + w(y), the distance |z + u(z) − y| (mm), over the source voxels `over` names.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct RoundTrip {
    /// Mean distance over the voxels with a preimage (mm).
    pub mean_mm: f64,
    /// Largest distance over them (mm).
    pub max_mm: f64,
    /// Share of them farther than 0.1 mm: where the inversion did not converge (the field
    /// folds or compresses sharply there).
    pub over_tenth_mm: f64,
    /// Share of the voxels with no preimage in the target's field of view (the target never
    /// saw them; their inverse is extrapolated from the field's edge).
    pub without_preimage: f64,
    /// Which voxels.
    pub over: &'static str,
}

/// The inverse of `field` sampled on `grid` (3 floats per voxel, where the backend computes)
/// and its residual per voxel (see [`Backend::invert_field`]).
pub fn invert<B: Backend>(
    backend: &B,
    field: &DeviceImage<B>,
    grid: &Grid,
) -> Result<(DeviceImage<B>, B::Buffer<f32>)> {
    let params = InvertParams::new(&field.grid, grid);
    let (inverse, residual) = backend.invert_field(&params, &field.data)?;
    let inverse = DeviceImage {
        data: inverse,
        grid: grid.clone(),
    };
    Ok((inverse, residual))
}

/// Residual (mm) beyond which the inversion counts as not converged.
const FAR_MM: f32 = 0.1;

/// The round trip of the inverse whose per-voxel `residual` (see [`invert`]) is on the grid of
/// `source`, over the source's body (its voxels above 0), reduced where the backend computes:
/// only a few numbers per chunk of voxels come back.
pub fn round_trip<B: Backend>(
    backend: &B,
    residual: &B::Buffer<f32>,
    source: &DeviceImage<B>,
) -> Result<RoundTrip> {
    let params = RoundTripParams::new(source.grid.len(), FAR_MM);
    let stats =
        backend.download_one(&backend.round_trip_stats(&params, residual, &source.data)?)?;
    let (mut sum, mut max, mut with, mut far, mut without) = (0.0f64, 0.0f64, 0.0, 0.0, 0.0);
    for chunk in stats.chunks_exact(ROUND_TRIP_WIDTH) {
        sum += chunk[0];
        max = max.max(chunk[1]);
        with += chunk[2];
        far += chunk[3];
        without += chunk[4];
    }
    Ok(RoundTrip {
        mean_mm: if with > 0.0 { sum / with } else { 0.0 },
        max_mm: max,
        over_tenth_mm: far / with.max(1.0),
        without_preimage: without / (with + without).max(1.0),
        over: "the source's voxels above 0 (its body)",
    })
}
