//! `posereg bend SOURCE --labels LABELS --degrees D [--axis ...] -o DIR`: the paper's synthetic
//! experiment — bend a labelled volume with volume skeletal deformation and keep the truth.

use super::progress::Reporter;
use clap::Args;
use posereg::abi::Blending;
use posereg::abi::Interpolation;
use posereg::backend::resample_volume;
use posereg::device::{open_backend, DeviceWanted};
use posereg::init::repose::{bend, check_bend_degrees, Posed};
use posereg::io::field::save_field;
use posereg::io::nifti::{load_labels, load_volume, save_labels, save_volume, DataType};
use posereg::joints::joint::{flexion_axis, JointAxis, KneeBones};
use posereg::{Error, Labels, Volume};
use std::path::{Path, PathBuf};

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
    #[arg(long, value_enum, default_value_t = Blending::Linear)]
    pub blending: Blending,
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
        args.blending,
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

/// The scan `pose` and `bend` move and its bone labels, read and checked before any work: the
/// labels on the scan's grid.
pub fn load_posable(source: &Path, labels: &Path) -> anyhow::Result<(Volume, Labels)> {
    let volume = load_volume(source)?;
    let label_map = load_labels(labels)?;
    if !label_map.grid.same_as(&volume.grid, 1e-3) {
        return Err(Error::bad_file(labels, "label map is not on the source image's grid").into());
    }
    Ok((volume, label_map))
}

/// Writes a synthetic pose of `source` and its `labels` into `folder`: target.nii.gz,
/// target_labels.nii.gz, truth_field.nii.gz, truth.json and picture.png (three planes through
/// `knee`).
pub fn write_posed(
    opened: &posereg::device::Opened,
    folder: &std::path::Path,
    (source, labels): (&posereg::Volume, &posereg::Labels),
    posed: &Posed,
    knee: [f64; 3],
) -> anyhow::Result<()> {
    let out = |name: &str| folder.join(name);
    let target = posereg::on_backend!(opened, backend => resample_volume(backend, source, &posed.field, 0.0, Interpolation::Linear))?;
    let label_values: posereg::Volume = posereg::Image {
        grid: labels.grid.clone(),
        data: labels.data.iter().map(|&l| l as f32).collect(),
    };
    let target_labels = posereg::on_backend!(opened, backend => resample_volume(backend, &label_values, &posed.field, 0.0, Interpolation::Nearest))?;
    save_volume(&out("target.nii.gz"), &target, DataType::F32)?;
    save_labels(
        &out("target_labels.nii.gz"),
        &posereg::Image {
            grid: target_labels.grid,
            data: target_labels.data.iter().map(|&v| v as u16).collect(),
        },
    )?;
    save_field(&out("truth_field.nii.gz"), &posed.field)?;
    posed.truth.save(&out("truth.json"))?;
    posereg::report::picture::save_planes_png(&out("picture.png"), &target, Some(knee))?;
    Ok(())
}
