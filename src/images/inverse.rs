//! The inverse of a registration's field: where each source point lies in the target, so that
//! images and labels drawn on the target can be brought back onto the source
//! (`inverse_field.nii.gz`, `posereg apply --inverse`), with how well it undoes the field.

use crate::abi::InvertParams;
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

/// The round trip of a residual volume over the voxels `inside` accepts.
pub fn round_trip(
    residual: &[f32],
    inside: impl Fn(usize) -> bool,
    over: &'static str,
) -> RoundTrip {
    let (mut sum, mut max, mut with, mut without, mut far) = (0.0f64, 0.0f64, 0, 0, 0);
    for (n, &r) in residual.iter().enumerate() {
        match (inside(n), r < 0.0) {
            (false, _) => {}
            (true, true) => without += 1,
            (true, false) => {
                sum += r as f64;
                max = max.max(r as f64);
                with += 1;
                far += (r > 0.1) as usize;
            }
        }
    }
    RoundTrip {
        mean_mm: if with > 0 { sum / with as f64 } else { 0.0 },
        max_mm: max,
        over_tenth_mm: far as f64 / with.max(1) as f64,
        without_preimage: without as f64 / (with + without).max(1) as f64,
        over,
    }
}
