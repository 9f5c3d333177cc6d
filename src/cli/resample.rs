//! `posereg resample SOURCE --field FIELD --like TARGET -o OUT`.

use clap::Args;
use posereg::backend::resample_volume;
use posereg::device::{open_backend, DeviceWanted};
use posereg::io::field::load_field;
use posereg::io::nifti::{save_volume, DataType};
use posereg::io::{check_output_file, NIFTI_NAMES};
use posereg::jobs::fields::{check_on_field_grid, interpolation, load_moving};
use posereg::jobs::reporter::Reporter;
use posereg::progress::Progress;
use std::path::PathBuf;

/// Arguments of `posereg resample`.
#[derive(Args, Debug)]
pub struct ResampleArgs {
    /// The image to move (.nii/.nii.gz).
    pub source: PathBuf,
    /// Displacement field on the target grid, ITK convention (LPS mm, target → source).
    #[arg(long)]
    pub field: PathBuf,
    /// The target image: the output takes its grid and affine.
    #[arg(long)]
    pub like: PathBuf,
    /// Output file (.nii or .nii.gz).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Value for points that fall outside the source.
    #[arg(long, default_value_t = 0.0)]
    pub background: f32,
    /// Nearest-neighbour interpolation (for label maps).
    #[arg(long)]
    pub nearest: bool,
    /// Voxel type of the output.
    #[arg(long, value_enum, default_value_t = DataType::F32)]
    pub dtype: DataType,
}

/// Applies the field and writes the resampled image.
pub fn run(args: &ResampleArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    check_output_file(&args.output, NIFTI_NAMES)?;
    if !args.background.is_finite() {
        let problem = format!(
            "--background is {}: it must be a finite number",
            args.background
        );
        return Err(posereg::Error::InvalidInput(problem).into());
    }
    let field = load_field(&args.field)?;
    check_on_field_grid(&args.like, &field, &args.field)?;
    let source = load_moving(&args.source, args.nearest, &field)?;
    let (opened, line) = open_backend(device)?;
    reporter.say(&line);
    let warped = posereg::on_backend!(opened, backend => resample_volume(
        backend,
        &source,
        &field,
        args.background,
        interpolation(args.nearest),
    ))?;
    if let Some((lo, hi)) = args.dtype.integer_range() {
        let clipped = warped
            .data
            .iter()
            .filter(|&&v| v < lo - 0.5 || v > hi + 0.5)
            .count();
        if clipped > 0 {
            reporter.warn(&format!(
                "{clipped} voxels lie outside {:?}'s range {lo}..{hi} and are clipped to it",
                args.dtype
            ));
        }
    }
    save_volume(&args.output, &warped, args.dtype)?;
    Ok(())
}
