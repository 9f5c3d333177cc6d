//! `posereg apply-points DIR/transform.json POINTS.csv -o OUT.csv [--direction ...]`.
//!
//! Points are world RAS mm in a CSV with a header naming x, y, z (other columns are kept, in
//! order; no quoted commas). By default points marked on the source (straight) scan are carried
//! to where the same material lies in the target (bent) scan — what a user who marked landmarks
//! on one scan wants to find on the other; `--direction target-to-source` goes the other way.

use super::fields::registration_field;
use super::progress::Reporter;
use clap::{Args, ValueEnum};
use nalgebra::Vector3;
use posereg::images::points::{source_to_target, target_to_source};
use posereg::io::points::load_points;
use posereg::Error;
use std::path::{Path, PathBuf};

/// Which way points travel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Direction {
    /// From the source (straight) scan to the target (bent) scan.
    SourceToTarget,
    /// From the target scan to the source scan.
    TargetToSource,
}

/// Arguments of `posereg apply-points`.
#[derive(Args, Debug)]
pub struct PointsArgs {
    /// A registration's transform.json (its field.nii.gz is read from the same folder).
    pub transform: PathBuf,
    /// CSV of points with a header x,y,z (world RAS mm).
    pub points: PathBuf,
    /// Output CSV.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Which way the points travel.
    #[arg(long, value_enum, default_value_t = Direction::SourceToTarget)]
    pub direction: Direction,
}

/// Reads, maps, writes.
pub fn run(args: &PointsArgs, reporter: &Reporter) -> anyhow::Result<()> {
    posereg::io::check_output_file(&args.output, &[])?;
    let (field_path, field) = registration_field(&args.transform, false)?;
    let mut table = load_points(&args.points)?;
    let grid = &field.grid;
    // The field is defined on the target grid only: outside it any answer is extrapolation.
    let outside = |p: &Vector3<f64>| !grid.contains(p);
    let mapped: Vec<(Vector3<f64>, f64)> = match args.direction {
        Direction::SourceToTarget => source_to_target(&field, &table.points),
        Direction::TargetToSource => {
            refuse_outside(&args.points, &table.points, &outside, "lies", &field_path)?;
            target_to_source(&field, &table.points)
                .into_iter()
                .map(|p| (p, 0.0))
                .collect()
        }
    };
    if args.direction == Direction::SourceToTarget {
        let targets: Vec<Vector3<f64>> = mapped.iter().map(|m| m.0).collect();
        refuse_outside(
            &args.points,
            &targets,
            &outside,
            "maps to a point",
            &field_path,
        )?;
    }
    // The inversion is fixed-point iteration: where the field folds or compresses sharply it
    // may stop short, and the residual says by how much.
    let voxel = grid.finest_spacing();
    let poor = mapped
        .iter()
        .filter(|(_, residual)| *residual > voxel)
        .count();
    if poor > 0 {
        reporter.warn(&format!(
            "{poor} of {} points were inverted only to more than a voxel ({voxel:.2} mm); see \
             the inversion_residual_mm column of {}",
            mapped.len(),
            args.output.display()
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
    posereg::io::write_bytes(&args.output, out)?;
    Ok(())
}

/// Refuses the first point outside the field's grid, naming its row (row 1 is the header).
fn refuse_outside(
    path: &Path,
    points: &[Vector3<f64>],
    outside: &dyn Fn(&Vector3<f64>) -> bool,
    what: &str,
    field_path: &Path,
) -> anyhow::Result<()> {
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
        )
        .into());
    }
    Ok(())
}
