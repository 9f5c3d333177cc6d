//! The paper's figures for a registration against known truth: mean distance between the
//! estimated and true source points, share within 2 and 4 voxels, and image correlation.

use crate::error::{Error, Result};
use crate::volume::Field;

/// Field error statistics over a mask.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FieldError {
    /// Voxels compared.
    pub voxels: usize,
    /// Mean |u_est − u_true| (mm).
    pub mean_mm: f64,
    /// Median (mm).
    pub median_mm: f64,
    /// 95th percentile (mm).
    pub p95_mm: f64,
    /// Share within 2 voxels (of the largest voxel spacing).
    pub within_2_voxels: f64,
    /// Share within 4 voxels.
    pub within_4_voxels: f64,
}

/// Compares two fields on the same grid over the voxels where `mask` holds.
pub fn field_error(
    estimate: &Field,
    truth: &Field,
    mask: impl Fn(usize) -> bool,
) -> Result<FieldError> {
    if !estimate.grid.same_as(&truth.grid, 1e-3) {
        return Err(Error::InvalidInput(
            "estimated and true fields are on different grids".into(),
        ));
    }
    let voxel = estimate.grid.spacing().iter().cloned().fold(0.0, f64::max);
    let mut errors: Vec<f64> = (0..estimate.data.len())
        .filter(|&n| mask(n))
        .map(|n| {
            let (a, b) = (estimate.data[n], truth.data[n]);
            (0..3)
                .map(|c| ((a[c] - b[c]) as f64).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    if errors.is_empty() {
        return Err(Error::InvalidInput("the evaluation mask is empty".into()));
    }
    errors.sort_by(f64::total_cmp);
    let n = errors.len();
    let share = |limit: f64| errors.iter().filter(|&&e| e <= limit).count() as f64 / n as f64;
    Ok(FieldError {
        voxels: n,
        mean_mm: errors.iter().sum::<f64>() / n as f64,
        median_mm: errors[n / 2],
        p95_mm: errors[(n * 95 / 100).min(n - 1)],
        within_2_voxels: share(2.0 * voxel),
        within_4_voxels: share(4.0 * voxel),
    })
}

/// Target voxels whose source point (p + u(p)) lies inside the source grid, at least `margin`
/// voxels from its outermost voxel centres (−0.5: anywhere in the voxels' extent, the samplers'
/// rule): with the true field, the voxels both scans saw. Elsewhere the target shows anatomy
/// outside the source's field of view, which no registration can recover.
pub fn seen_by_both(truth: &Field, source: &crate::volume::Grid, margin: f64) -> Vec<bool> {
    use rayon::prelude::*;
    let grid = &truth.grid;
    let to_source = source.world_to_voxel_affine();
    (0..grid.len())
        .into_par_iter()
        .map(|n| {
            let w = grid.world_of(n);
            let u = truth.data[n];
            let q = to_source
                * nalgebra::Vector4::new(
                    w[0] + u[0] as f64,
                    w[1] + u[1] as f64,
                    w[2] + u[2] as f64,
                    1.0,
                );
            [q.x, q.y, q.z]
                .iter()
                .zip(source.dims)
                .all(|(v, n)| *v >= margin && *v <= (n - 1) as f64 - margin)
        })
        .collect()
}
