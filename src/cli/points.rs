//! `posereg apply-points DIR/transform.json POINTS.csv -o OUT.csv [--direction ...]`: points
//! (a CSV with columns x, y, z, world RAS mm) carried through a registration
//! (posereg::jobs::points).

use clap::{Args, ValueEnum};
use posereg::jobs::points::{carry_points, Direction};
use posereg::jobs::reporter::Reporter;
use std::path::PathBuf;

/// Which way points travel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Way {
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
    #[arg(long, value_enum, default_value_t = Way::SourceToTarget)]
    pub direction: Way,
}

/// Reads, maps, writes.
pub fn run(args: &PointsArgs, reporter: &Reporter) -> anyhow::Result<()> {
    let files = (
        args.transform.as_path(),
        args.points.as_path(),
        args.output.as_path(),
    );
    let direction = match args.direction {
        Way::SourceToTarget => Direction::SourceToTarget,
        Way::TargetToSource => Direction::TargetToSource,
    };
    carry_points(files, direction, reporter)?;
    Ok(())
}
