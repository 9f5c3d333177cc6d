//! A bone as a point cloud: the world positions of its label's voxels, their centroid and
//! principal directions (what the flexion axis and the anatomical frames are measured on).

use crate::volume::Labels;
use nalgebra::{Matrix3, Vector3};

/// World RAS mm of every voxel labelled `code`.
pub fn world_points(labels: &Labels, code: u16) -> Vec<Vector3<f64>> {
    labels
        .data
        .iter()
        .enumerate()
        .filter(|(_, &l)| l == code)
        .map(|(n, _)| labels.grid.world_of(n))
        .collect()
}

/// Mean of the points (callers pass at least one).
pub fn centroid(points: &[Vector3<f64>]) -> Vector3<f64> {
    points.iter().sum::<Vector3<f64>>() / points.len() as f64
}

/// The points' scatter about their centroid (unnormalised covariance), after projecting out
/// `remove` (if any).
fn scatter(points: &[Vector3<f64>], remove: Option<Vector3<f64>>) -> Matrix3<f64> {
    let c = centroid(points);
    let mut cov = Matrix3::zeros();
    for p in points {
        let mut d = p - c;
        if let Some(r) = remove {
            d -= r * r.dot(&d);
        }
        cov += d * d.transpose();
    }
    cov
}

/// Eigenvector of the points' covariance with the largest eigenvalue, after projecting out
/// `remove` (if any).
pub fn principal_direction(points: &[Vector3<f64>], remove: Option<Vector3<f64>>) -> Vector3<f64> {
    let eig = scatter(points, remove).symmetric_eigen();
    let k = eig.eigenvalues.imax();
    eig.eigenvectors.column(k).into_owned().normalize()
}

/// The points' three principal directions, as the columns of a matrix (in no set order).
pub fn principal_directions(points: &[Vector3<f64>]) -> Matrix3<f64> {
    scatter(points, None).symmetric_eigen().eigenvectors
}

/// The points within `depth` mm of the cloud's end along `direction` (its extreme in that
/// direction): a bone's end, such as the femoral condyles or the tibial plateau.
pub fn end_slab(points: &[Vector3<f64>], direction: Vector3<f64>, depth: f64) -> Vec<Vector3<f64>> {
    let far = points
        .iter()
        .map(|p| p.dot(&direction))
        .fold(f64::NEG_INFINITY, f64::max);
    points
        .iter()
        .filter(|p| p.dot(&direction) >= far - depth)
        .copied()
        .collect()
}
