//! Moving points with a registration's field (target point p → source point p + u(p)).
//!
//! `target_to_source` is direct. `source_to_target` inverts the field: the target point p whose
//! source point is x, found from the nearest target voxel whose source point lies closest to x,
//! then fixed-point steps p ← x − u(p) with u trilinear; the residual |p + u(p) − x| is reported.

use crate::cpu::sample::trilinear;
use crate::volume::Field;
use nalgebra::Vector3;
use rayon::prelude::*;

/// u at world point p (trilinear, clamped to the field's grid).
pub fn displacement_at(
    field: &Field,
    components: &[Vec<f32>; 3],
    p: &Vector3<f64>,
) -> Vector3<f64> {
    let q = field.grid.world_to_voxel_affine() * p.push(1.0);
    let dims = field.grid.dims.map(|d| d as u32);
    let qc: [f32; 3] = std::array::from_fn(|a| (q[a] as f32).clamp(0.0, dims[a] as f32 - 1.0));
    Vector3::from_fn(|c, _| trilinear(&components[c], qc, dims, 0.0) as f64)
}

/// The field split into its three components (what [`displacement_at`] samples).
pub fn components(field: &Field) -> [Vec<f32>; 3] {
    std::array::from_fn(|c| field.data.iter().map(|v| v[c]).collect())
}

/// Target → source: x + u(x).
pub fn target_to_source(field: &Field, points: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    let comps = components(field);
    points
        .iter()
        .map(|p| p + displacement_at(field, &comps, p))
        .collect()
}

/// Source → target, with the inversion residual (mm) of each point.
pub fn source_to_target(field: &Field, points: &[Vector3<f64>]) -> Vec<(Vector3<f64>, f64)> {
    let comps = components(field);
    let grid = &field.grid;
    let voxel_source: Vec<(Vector3<f64>, Vector3<f64>)> = (0..grid.len())
        .into_par_iter()
        .map(|n| {
            let p = grid.world_of(n);
            let u = field.data[n];
            (p, p + Vector3::new(u[0] as f64, u[1] as f64, u[2] as f64))
        })
        .collect();
    points
        .par_iter()
        .map(|x| {
            let start = voxel_source
                .iter()
                .min_by(|a, b| (a.1 - x).norm().total_cmp(&(b.1 - x).norm()))
                .map(|v| v.0)
                .unwrap_or(*x);
            let mut p = start;
            for _ in 0..50 {
                let next = x - displacement_at(field, &comps, &p);
                let moved = (next - p).norm();
                p = next;
                if moved < 1e-4 {
                    break;
                }
            }
            let residual = (p + displacement_at(field, &comps, &p) - x).norm();
            (p, residual)
        })
        .collect()
}
