//! `posereg apply DIR/transform.json IMAGE --like TARGET -o OUT [--nearest]`: applies a
//! registration to another image on the source's grid (a label map with --nearest). The total
//! field is the registration's field.nii.gz, beside its transform.json: the composed warp
//! (articulated initialisation and RBF) sampled on the target grid, which is what the warped
//! image was made with, so applying it reproduces that resampling exactly.

use clap::Args;
use posereg::abi::Interpolation;
use posereg::device::{open_backend, DeviceChoice};
use posereg::io::field::load_field;
use posereg::io::nifti::{load_volume, read_raw, save_volume, DataType};
use posereg::io::transform::BoneTransforms;
use posereg::Error;
use std::path::PathBuf;

/// Arguments of `posereg apply`.
#[derive(Args, Debug)]
pub struct ApplyArgs {
    /// A registration's transform.json (its field.nii.gz is read from the same folder).
    pub transform: PathBuf,
    /// The image to move (on the source's grid or any other: it is sampled in world space).
    pub image: PathBuf,
    /// The target image: the output takes its grid and affine.
    #[arg(long)]
    pub like: PathBuf,
    /// Output file (.nii or .nii.gz).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Nearest-neighbour interpolation (label maps), written as integers.
    #[arg(long)]
    pub nearest: bool,
}

/// Applies the registration's field to the image.
pub fn run(args: &ApplyArgs, device: DeviceChoice) -> anyhow::Result<()> {
    BoneTransforms::load(&args.transform)?;
    let folder = args
        .transform
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    let field_path = folder.join("field.nii.gz");
    let field = load_field(&field_path)?;
    let like = read_raw(&args.like)?;
    let dims: Vec<usize> = like.info.dims.iter().take(3).copied().collect();
    if dims != field.grid.dims || (like.info.affine - field.grid.affine).abs().max() > 1e-3 {
        return Err(Error::bad_file(
            &args.like,
            format!(
                "is not on the registration's target grid ({})",
                field_path.display()
            ),
        )
        .into());
    }
    let image = load_volume(&args.image)?;
    let (backend, line) = open_backend(device)?;
    eprintln!("{line}");
    let interpolation = if args.nearest {
        Interpolation::Nearest
    } else {
        Interpolation::Linear
    };
    let moved = backend.resample(&image, &field, 0.0, interpolation)?;
    let dtype = if args.nearest {
        DataType::I32
    } else {
        DataType::F32
    };
    save_volume(&args.output, &moved, dtype)?;
    Ok(())
}
