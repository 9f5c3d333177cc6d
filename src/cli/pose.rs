//! `posereg pose SOURCE --labels LABELS --flexion D [--varus D] ... -o DIR`: the source
//! re-posed at given tibiofemoral joint angles and translations (Grood & Suntay, as
//! kinematics.csv reports them), with its exact truth: for checking a result, and for making
//! test pairs whose motion is not a rotation about one axis.

use super::BlendingFlag;
use clap::Args;
use posereg::device::{open_backend, DeviceWanted};
use posereg::init::repose::{check_pose_change, pose};
use posereg::jobs::posed::{load_posable, write_posed};
use posereg::jobs::reporter::Reporter;
use posereg::joints::anatomy::{knee_frames, Side};
use posereg::joints::joint::KneeBones;
use posereg::joints::kinematics::JointPose;
use posereg::progress::Progress;
use posereg::Error;
use std::path::PathBuf;

/// Arguments of `posereg pose`: the change from the source's pose.
#[derive(Args, Debug)]
pub struct PoseArgs {
    /// The source image (posereg's label codes: 2 femur, 3 tibia, 4 patella, 5 fibula).
    pub source: PathBuf,
    /// Its bone labels.
    #[arg(long)]
    pub labels: PathBuf,
    /// Flexion added (degrees; knee bending positive).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub flexion: f64,
    /// Varus added (degrees; valgus negative).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub varus: f64,
    /// Internal rotation of the tibia added (degrees; external negative).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub internal_rotation: f64,
    /// Lateral shift of the tibia added (mm).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub lateral_shift: f64,
    /// Anterior drawer added (mm).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub anterior_drawer: f64,
    /// Compression added (mm; distraction negative).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub compression: f64,
    /// Which knee (default: from the labels' fibula).
    #[arg(long, value_enum)]
    pub side: Option<Side>,
    /// How the bone motions are blended across the soft tissue.
    #[arg(long, value_enum, default_value_t = BlendingFlag::Linear)]
    pub blending: BlendingFlag,
    /// Output folder.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Poses and writes target.nii.gz, target_labels.nii.gz, truth_field.nii.gz, truth.json and
/// picture.png.
pub fn run(args: &PoseArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let change = JointPose {
        flexion_deg: args.flexion,
        about_e2_deg: args.varus,
        about_e3_deg: args.internal_rotation,
        lateral_mm: args.lateral_shift,
        anterior_mm: args.anterior_drawer,
        proximal_mm: args.compression,
    };
    check_pose_change(change)?;
    let _folder = posereg::io::prepare_output_folder(&args.output)?;
    let (source, labels) = load_posable(&args.source, &args.labels)?;
    knee_frames(&labels, KneeBones::default())
        .map_err(|e| Error::bad_file(&args.labels, e.to_string()))?;
    let (opened, line) = open_backend(device)?;
    reporter.say(&line);
    let posed = posereg::on_backend!(opened, backend => pose(
        backend, &source, &labels, change, args.side, args.blending.into(),
    ))?;
    let axis = posereg::joints::joint::flexion_axis(
        &labels,
        posereg::joints::joint::KneeBones::default(),
    )?;
    let knee = [axis.point.x, axis.point.y, axis.point.z];
    write_posed(&opened, &args.output, (&source, &labels), &posed, knee)?;
    reporter.result(&format!("posed; written to {}", args.output.display()));
    Ok(())
}
