//! `posereg bend SOURCE --labels LABELS --degrees D [--axis ...] -o DIR`: the paper's synthetic
//! experiment — bend a labelled volume with volume skeletal deformation and keep the truth.

use super::BlendingFlag;
use clap::Args;
use posereg::device::{open_backend, DeviceWanted};
use posereg::init::repose::{bend, check_bend_degrees};
use posereg::jobs::posed::{load_posable, write_posed};
use posereg::jobs::reporter::Reporter;
use posereg::joints::joint::{flexion_axis, JointAxis, KneeBones};
use posereg::progress::Progress;
use posereg::Error;
use std::path::PathBuf;

/// Arguments of `posereg bend`.
#[derive(Args, Debug)]
pub struct BendArgs {
    /// The straight-pose image.
    pub source: PathBuf,
    /// Its bone labels (2 femur, 3 tibia, 4 patella, 5 fibula).
    #[arg(long)]
    pub labels: PathBuf,
    /// Flexion angle (degrees).
    #[arg(long)]
    pub degrees: f64,
    /// Flexion axis as px,py,pz,dx,dy,dz (world RAS mm; a point and a direction). Default:
    /// found from the labels, through the femoral condyles.
    #[arg(long, value_delimiter = ',', num_args = 6)]
    pub axis: Option<Vec<f64>>,
    /// How the bone motions are blended across the soft tissue.
    #[arg(long, value_enum, default_value_t = BlendingFlag::Linear)]
    pub blending: BlendingFlag,
    /// Output folder.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// The axis of `--axis px,py,pz,dx,dy,dz`: finite, a non-zero direction (scaled before it is
/// normalised, so 1e300 does not overflow to a zero vector), through a point of the source.
fn given_axis(a: &[f64], source: &posereg::volume::Grid) -> anyhow::Result<JointAxis> {
    let point = nalgebra::Vector3::new(a[0], a[1], a[2]);
    let direction = nalgebra::Vector3::new(a[3], a[4], a[5]);
    let largest = direction.amax();
    if !a.iter().all(|v| v.is_finite()) || largest == 0.0 {
        let problem = "--axis must be six finite numbers with a non-zero direction";
        return Err(Error::InvalidInput(problem.into()).into());
    }
    if !source.contains(&point) {
        let problem = format!(
            "--axis point {:?} lies outside the source image",
            a[..3].to_vec()
        );
        return Err(Error::InvalidInput(problem).into());
    }
    Ok(JointAxis {
        point,
        direction: (direction / largest).normalize(),
        long_axis: nalgebra::Vector3::z(),
        anterior: nalgebra::Vector3::y(),
    })
}

/// Bends and writes target.nii.gz, target_labels.nii.gz, truth_field.nii.gz, truth.json and
/// picture.png (three planes through the knee).
pub fn run(args: &BendArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    check_bend_degrees(args.degrees).map_err(|e| anyhow::anyhow!("--degrees: {e}"))?;
    let _folder = posereg::io::prepare_output_folder(&args.output)?;
    let (source, labels) = load_posable(&args.source, &args.labels)?;
    let axis = match &args.axis {
        Some(a) => given_axis(a, &source.grid)?,
        None => flexion_axis(&labels, KneeBones::default())
            .map_err(|e| Error::bad_file(&args.labels, e.to_string()))?,
    };
    let (opened, line) = open_backend(device)?;
    reporter.say(&line);
    let (bent, axis) = posereg::on_backend!(opened, backend => bend(
        backend,
        &source,
        &labels,
        args.degrees,
        Some(axis),
        args.blending.into(),
    ))?;
    let knee = [axis.point.x, axis.point.y, axis.point.z];
    write_posed(&opened, &args.output, (&source, &labels), &bent, knee)?;
    println!(
        "bent {}° about the axis through {:.1?} along {:.3?}; written to {}",
        args.degrees,
        axis.point.as_slice(),
        axis.direction.as_slice(),
        args.output.display()
    );
    Ok(())
}
