//! Points carried through a registration (`posereg apply-points`). Points are world RAS mm in
//! a CSV with a header naming x, y, z (other columns are kept, in order; no quoted commas). By
//! default points marked on the source (straight) scan are carried to where the same material
//! lies in the target (bent) scan, what a user who marked landmarks on one scan wants to find
//! on the other; target to source goes the other way.

use super::fields::registration_field;
use crate::error::{Error, Result};
use crate::images::points::{source_to_target, target_to_source};
use crate::io::points::load_points;
use crate::progress::Progress;
use nalgebra::Vector3;
use std::path::Path;

/// Which way points travel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// From the source (straight) scan to the target (bent) scan.
    SourceToTarget,
    /// From the target scan to the source scan.
    TargetToSource,
}

/// Reads the points, carries them through the registration `transform` belongs to the way
/// `direction` says, and writes them, with each one's inversion residual, to `output`.
pub fn carry_points(
    (transform, points, output): (&Path, &Path, &Path),
    direction: Direction,
    progress: &dyn Progress,
) -> Result<()> {
    crate::io::check_output_file(output, &[])?;
    let (field_path, field) = registration_field(transform, false)?;
    let mut table = load_points(points)?;
    let grid = &field.grid;
    // The field is defined on the target grid only: outside it any answer is extrapolation.
    let outside = |p: &Vector3<f64>| !grid.contains(p);
    let mapped: Vec<(Vector3<f64>, f64)> = match direction {
        Direction::SourceToTarget => source_to_target(&field, &table.points),
        Direction::TargetToSource => {
            refuse_outside(points, &table.points, &outside, "lies", &field_path)?;
            target_to_source(&field, &table.points)
                .into_iter()
                .map(|p| (p, 0.0))
                .collect()
        }
    };
    if direction == Direction::SourceToTarget {
        let targets: Vec<Vector3<f64>> = mapped.iter().map(|m| m.0).collect();
        refuse_outside(points, &targets, &outside, "maps to a point", &field_path)?;
    }
    // The inversion is fixed-point iteration: where the field folds or compresses sharply it
    // may stop short, and the residual says by how much.
    let voxel = grid.finest_spacing();
    let poor = mapped
        .iter()
        .filter(|(_, residual)| *residual > voxel)
        .count();
    if poor > 0 {
        progress.warn(&format!(
            "{poor} of {} points were inverted only to more than a voxel ({voxel:.2} mm); see \
             the inversion_residual_mm column of {}",
            mapped.len(),
            output.display()
        ));
    }
    let [cx, cy, cz] = table.columns;
    let mut out = table.header.join(",") + ",inversion_residual_mm\n";
    for (cells, (p, residual)) in table.rows.iter_mut().zip(&mapped) {
        cells[cx] = format!("{:.4}", p.x);
        cells[cy] = format!("{:.4}", p.y);
        cells[cz] = format!("{:.4}", p.z);
        out += &format!("{},{residual:.4}\n", cells.join(","));
    }
    crate::io::write_bytes(output, out)?;
    Ok(())
}

/// Refuses the first point outside the field's grid, naming its row (row 1 is the header).
fn refuse_outside(
    path: &Path,
    points: &[Vector3<f64>],
    outside: &dyn Fn(&Vector3<f64>) -> bool,
    what: &str,
    field_path: &Path,
) -> Result<()> {
    if let Some(k) = points.iter().position(outside) {
        let p = points[k];
        return Err(Error::bad_file(
            path,
            format!(
                "point {} {what} ({:.1}, {:.1}, {:.1}) outside the grid of {}, where the \
                 registration is not defined",
                k + 1,
                p.x,
                p.y,
                p.z,
                field_path.display()
            ),
        ));
    }
    Ok(())
}
