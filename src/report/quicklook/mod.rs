//! quicklook.png: one labelled picture to judge a registration by eye.
//!
//! Rows: sagittal, coronal and axial planes through the knee. Columns: the target, the source
//! as it lies, the warped source, a checkerboard of target and warped, |target − warped| and
//! the field's Jacobian determinant with its colour scale. Every panel has the same size. The
//! bones' outlines (the source's labels carried by the field) are drawn over the target and the
//! checkerboard, so a bone that does not sit on the target's bone shows; target voxels whose
//! source point lies outside the source scan are hatched where the warped source appears (they
//! hold no data, not a mismatch). Control points near each plane are drawn on the warped
//! column as in the paper's figures 2–3, and the bones' anatomical frames (the kinematics'
//! axes, carried into the target's pose) on the target column, projected onto each plane. A footer gives the correlation and the mean |target −
//! source| before and after, over the target's body, and the legends. chart.rs draws
//! `posereg series`' series.png.

pub mod chart;
mod draw;
mod panels;

use crate::error::{Error, Result};
use crate::joints::anatomy::Frame;
use crate::nonrigid::adaptive::ControlPoint;
use crate::report::picture::{pixel_size, window, world_bounds, PLANES};
use crate::report::result_checks::Correlations;
use crate::volume::{Field, Grid, Labels, Volume};
use draw::Canvas;
use panels::{PlaneImages, Sampling};
use std::path::Path;

/// What the figure shows: volumes on the target's grid unless said otherwise.
pub struct Figure<'a> {
    /// The fixed scan.
    pub target: &'a Volume,
    /// The source resampled onto the target's grid as it lies.
    pub before: &'a Volume,
    /// The source resampled through the field.
    pub warped: &'a Volume,
    /// The field's Jacobian determinant.
    pub jacobian: &'a Volume,
    /// The field (target point → source point).
    pub field: &'a Field,
    /// The source scan's grid (where it holds data).
    pub source_grid: &'a Grid,
    /// The source's bone labels (on the source grid) and the bones' codes and names.
    pub labels: &'a Labels,
    /// The bones drawn, code and name.
    pub bones: &'a [(u16, String)],
    /// The adaptive stage's control points.
    pub points: &'a [ControlPoint],
    /// The point the planes pass through (world RAS mm).
    pub centre: [f64; 3],
    /// The bones' anatomical frames in the target pose (drawn on the target, projected).
    pub frames: &'a [Frame],
    /// The correlation of `before` and of `warped` with the target over its body.
    pub correlations: Correlations,
}

/// Column titles.
const COLUMNS: [&str; 6] = [
    "target (fixed)",
    "source as it lies",
    "warped source",
    "checkerboard",
    "|target - warped|",
    "Jacobian det J",
];
/// Row titles: the plane, the world axis it is normal to, which way the picture runs
/// (picture::PLANES).
const ROWS: [(&str, usize, &str); 3] = [
    ("sagittal", 0, "anterior on the left"),
    ("coronal", 1, "subject's right on the left"),
    ("axial", 2, "anterior up, right left"),
];

/// Writes the figure as a PNG (atomically).
pub fn save(path: &Path, figure: &Figure) -> Result<()> {
    let pixel = pixel_size(figure.target);
    let bounds = world_bounds(figure.target);
    let sampling = Sampling::new(figure);
    let rows: Vec<PlaneImages> = PLANES
        .iter()
        .map(|&axes| PlaneImages::new(figure, &sampling, bounds, axes, pixel))
        .collect();
    let levels = window(rows.iter().map(|r| &r.target));
    let mut canvas = Canvas::new(&rows, COLUMNS.len())?;
    canvas.titles(&COLUMNS, &ROWS, figure.centre);
    for (r, row) in rows.iter().enumerate() {
        canvas.row(r, row, levels, figure);
    }
    canvas.footer(&summary(figure), figure.bones);
    let img = canvas.into_image();
    crate::io::write_atomically(path, |tmp| {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|e| Error::bad_file(path, format!("cannot write PNG ({e})")))
    })
}

/// The footer's first line: correlation and mean |target − source| before and after.
fn summary(figure: &Figure) -> String {
    let target = &figure.target.data;
    let body = |n: usize| target[n] > 0.0;
    let mean_gap = |image: &Volume| {
        let (sum, n) = (0..target.len())
            .filter(|&n| body(n))
            .fold((0.0f64, 0usize), |(s, c), n| {
                (s + (target[n] - image.data[n]).abs() as f64, c + 1)
            });
        sum / n.max(1) as f64
    };
    format!(
        "Over the target's body: correlation {:.3} before -> {:.3} after; \
         mean |target - source| {:.1} before -> {:.1} after (intensity units)",
        figure.correlations.before,
        figure.correlations.after,
        mean_gap(figure.before),
        mean_gap(figure.warped)
    )
}
