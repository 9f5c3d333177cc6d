//! `posereg phantom -o DIR [--size ...] [--flexion DEG] [--bias B] [--noise N] [--seed S] [--png]`.

use clap::Args;
use posereg::io::field::save_field;
use posereg::io::nifti::{save_labels, save_volume, DataType};
use posereg::phantom::{generate, PhantomSize, PhantomSpec};
use std::path::PathBuf;

/// Arguments of `posereg phantom`.
#[derive(Args, Debug)]
pub struct PhantomArgs {
    /// Output folder (created if missing).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Grid: small 48×96×96, half 68×128×128 (2.5 mm), paper 136×256×256 (1.25 mm).
    #[arg(long, value_enum, default_value_t = PhantomSize::Paper)]
    pub size: PhantomSize,
    /// Knee flexion in degrees (0 to 120).
    #[arg(long, default_value_t = 0.0)]
    pub flexion: f64,
    /// Bias-field amplitude, relative (0 turns it off).
    #[arg(long, default_value_t = 0.15)]
    pub bias: f32,
    /// Rician noise σ relative to the brightest tissue (0 turns it off).
    #[arg(long, default_value_t = 0.02)]
    pub noise: f32,
    /// Seed for bias and noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also write picture.png: sagittal, coronal and axial planes through the knee.
    #[arg(long)]
    pub png: bool,
}

/// Builds the phantom and writes image, labels, truth field and truth.json.
pub fn run(args: &PhantomArgs) -> anyhow::Result<()> {
    let spec = PhantomSpec {
        size: args.size,
        flexion_degrees: args.flexion,
        bias: args.bias,
        noise: args.noise,
        seed: args.seed,
    };
    let _folder = posereg::io::prepare_output_folder(&args.output)?;
    let phantom = generate(&spec)?;
    let out = |name: &str| args.output.join(name);
    save_volume(&out("image.nii.gz"), &phantom.image, DataType::F32)?;
    save_labels(&out("labels.nii.gz"), &phantom.labels)?;
    save_field(&out("truth_field.nii.gz"), &phantom.truth_field)?;
    phantom.truth.save(&out("truth.json"))?;
    if args.png {
        // Through the knee: the flexion axis at the midline.
        let knee = posereg::phantom::flexion::Flexion::knee(0.0)
            .axis_point
            .as_dvec3()
            .to_array();
        posereg::report::picture::save_planes_png(&out("picture.png"), &phantom.image, Some(knee))?;
    }
    println!("phantom written to {}", args.output.display());
    Ok(())
}
