//! What the figure samples on one plane: the four volumes, where the warped source holds data,
//! and which bone the field carries each pixel to.

use super::Figure;
use crate::images::points::{components, displacement_at};
use crate::report::picture::{Panel, PlanePoints};
use crate::sample::{inside_source, nearest};
use crate::volume::Field;
use nalgebra::{Vector3, Vector4};

/// One plane's images, all on the same pixels.
pub struct PlaneImages {
    /// Where the pixels are.
    pub plane: PlanePoints,
    /// The target.
    pub target: Panel,
    /// The source as it lies.
    pub before: Panel,
    /// The warped source.
    pub warped: Panel,
    /// The Jacobian determinant.
    pub jacobian: Panel,
    /// Whether the pixel's source point lies inside the source scan.
    pub covered: Vec<bool>,
    /// The source label at the pixel's source point (0 outside).
    pub bone: Vec<u16>,
}

/// What every plane samples besides the volumes, prepared once for the figure: the field's
/// components and the source labels as values.
pub struct Sampling<'a> {
    field: &'a Field,
    components: [Vec<f32>; 3],
    codes: Vec<f32>,
}

impl<'a> Sampling<'a> {
    /// For `figure`.
    pub fn new(figure: &Figure<'a>) -> Self {
        Sampling {
            field: figure.field,
            components: components(figure.field),
            codes: figure.labels.data.iter().map(|&c| c as f32).collect(),
        }
    }

    /// The source point of target point `p` (None outside the field's grid).
    fn displaced(&self, p: &[f64; 3]) -> Option<[f64; 3]> {
        let p = Vector3::from(*p);
        self.field.grid.contains(&p).then(|| {
            let moved = p + displacement_at(self.field, &self.components, &p);
            [moved.x, moved.y, moved.z]
        })
    }
}

impl PlaneImages {
    /// The plane through the figure's centre spanned by `axes` (see picture::PLANES).
    pub fn new(
        figure: &Figure,
        sampling: &Sampling,
        bounds: ([f64; 3], [f64; 3]),
        axes: (usize, f64, usize),
        pixel: f64,
    ) -> Self {
        let plane = PlanePoints::new(bounds, figure.centre, axes, pixel);
        let source_points: Vec<Option<[f64; 3]>> =
            plane.points.iter().map(|p| sampling.displaced(p)).collect();
        let source_to_voxel = figure.source_grid.world_to_voxel_affine();
        let source_dims = figure.source_grid.dims.map(|d| d as u32);
        let in_source = |p: &[f64; 3]| {
            let q = source_to_voxel * Vector4::new(p[0], p[1], p[2], 1.0);
            [q.x as f32, q.y as f32, q.z as f32]
        };
        let covered = source_points
            .iter()
            .map(|p| p.is_some_and(|p| inside_source(in_source(&p), source_dims)))
            .collect();
        let label_dims = figure.labels.grid.dims.map(|d| d as u32);
        let bone = source_points
            .iter()
            .map(|p| {
                p.map_or(0, |p| {
                    nearest(&sampling.codes, in_source(&p), label_dims, 0.0) as u16
                })
            })
            .collect();
        PlaneImages {
            target: plane.sample(figure.target),
            before: plane.sample(figure.before),
            warped: plane.sample(figure.warped),
            jacobian: plane.sample(figure.jacobian),
            covered,
            bone,
            plane,
        }
    }
}
