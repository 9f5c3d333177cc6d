//! `posereg apply DIR/transform.json IMAGE --like TARGET -o OUT [--nearest] [--inverse]`:
//! applies a registration to another image on the source's grid (a label map with --nearest).
//! The total field is the registration's field.nii.gz, beside its transform.json: the composed
//! warp (articulated initialisation and RBF) sampled on the target grid, which is what the
//! warped image was made with, so applying it reproduces that resampling exactly. With
//! --inverse, an image on the target's grid is brought back onto the source's grid through
//! inverse_field.nii.gz.

use clap::Args;
use posereg::backend::resample_volume;
use posereg::device::{open_backend, DeviceWanted};
use posereg::io::nifti::{save_volume, DataType};
use posereg::io::{check_output_file, NIFTI_NAMES};
use posereg::jobs::fields::{check_on_field_grid, interpolation, load_moving, registration_field};
use posereg::jobs::reporter::Reporter;
use posereg::progress::Progress;
use std::path::PathBuf;

/// Arguments of `posereg apply`.
#[derive(Args, Debug)]
pub struct ApplyArgs {
    /// A registration's transform.json (its field.nii.gz is read from the same folder).
    pub transform: PathBuf,
    /// The image to move (on the source's grid or any other: it is sampled in world space; on
    /// the target's with --inverse).
    pub image: PathBuf,
    /// The target image (the source with --inverse): the output takes its grid and affine.
    #[arg(long)]
    pub like: PathBuf,
    /// Target → source: bring an image drawn on the target (a segmentation, say) back onto
    /// the source through inverse_field.nii.gz.
    #[arg(long)]
    pub inverse: bool,
    /// Output file (.nii or .nii.gz).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Nearest-neighbour interpolation (label maps), written as integers.
    #[arg(long)]
    pub nearest: bool,
}

/// Applies the registration's field to the image.
pub fn run(args: &ApplyArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    check_output_file(&args.output, NIFTI_NAMES)?;
    let (field_path, field) = registration_field(&args.transform, args.inverse)?;
    check_on_field_grid(&args.like, &field, &field_path)?;
    let image = load_moving(&args.image, args.nearest, &field)?;
    let (opened, line) = open_backend(device)?;
    reporter.say(&line);
    let moved = posereg::on_backend!(opened, backend => resample_volume(backend, &image, &field, 0.0, interpolation(args.nearest)))?;
    let dtype = if args.nearest {
        DataType::I32
    } else {
        DataType::F32
    };
    save_volume(&args.output, &moved, dtype)?;
    Ok(())
}
