//! `posereg apply-points DIR/transform.json POINTS.csv -o OUT.csv [--direction ...]`.
//!
//! Points are world RAS mm in a CSV with a header naming x, y, z (other columns are kept, in
//! order; no quoted commas). By default points marked on the source (straight) scan are carried
//! to where the same material lies in the target (bent) scan — what a user who marked landmarks
//! on one scan wants to find on the other; `--direction target-to-source` goes the other way.

use super::fields::registration_field;
use clap::{Args, ValueEnum};
use posereg::points::{source_to_target, target_to_source};
use posereg::Error;
use std::path::PathBuf;

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
pub fn run(args: &PointsArgs) -> anyhow::Result<()> {
    posereg::io::check_output_file(&args.output, &[])?;
    let (_, field) = registration_field(&args.transform)?;
    let text = std::fs::read_to_string(&args.points).map_err(|e| Error::io(&args.points, e))?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<String> = lines
        .next()
        .ok_or_else(|| Error::bad_file(&args.points, "is empty"))?
        .split(',')
        .map(|h| h.trim().to_lowercase())
        .collect();
    let column = |name: &str| {
        header.iter().position(|h| h == name).ok_or_else(|| {
            Error::bad_file(
                &args.points,
                format!("has no column {name:?} in its header"),
            )
        })
    };
    let (cx, cy, cz) = (column("x")?, column("y")?, column("z")?);
    let mut rows: Vec<Vec<String>> = Vec::new();
    let mut points = Vec::new();
    for (k, line) in lines.enumerate() {
        let cells: Vec<String> = line.split(',').map(|c| c.trim().to_string()).collect();
        let value = |c: usize| -> Result<f64, Error> {
            cells
                .get(c)
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    Error::bad_file(
                        &args.points,
                        format!("row {}: column {} is not a number", k + 2, header[c]),
                    )
                })
        };
        points.push(nalgebra::Vector3::new(value(cx)?, value(cy)?, value(cz)?));
        rows.push(cells);
    }
    let mapped: Vec<(nalgebra::Vector3<f64>, f64)> = match args.direction {
        Direction::SourceToTarget => source_to_target(&field, &points),
        Direction::TargetToSource => target_to_source(&field, &points)
            .into_iter()
            .map(|p| (p, 0.0))
            .collect(),
    };
    let mut out = header.join(",") + ",inversion_residual_mm\n";
    for (cells, (p, residual)) in rows.iter_mut().zip(&mapped) {
        cells[cx] = format!("{:.4}", p.x);
        cells[cy] = format!("{:.4}", p.y);
        cells[cz] = format!("{:.4}", p.z);
        out += &format!("{},{residual:.4}\n", cells.join(","));
    }
    posereg::io::write_atomically(&args.output, |tmp| {
        std::fs::write(tmp, &out).map_err(|e| Error::io(tmp, e))
    })?;
    Ok(())
}
