//! `posereg demo [-o DIR] [--size half] [--flexion 60]`: a phantom pair made on the spot and
//! registered (articulated initialisation, then adaptive cubic-RBF), with its figures
//! against the known truth.

use super::outputs::write_registration;
use super::progress::Reporter;
use clap::Args;
use posereg::device::{open_backend, DeviceWanted};
use posereg::init::articulated::bone_name;
use posereg::io::config::load_options;
use posereg::io::field::save_field;
use posereg::io::nifti::{save_labels, save_volume, DataType};
use posereg::io::transform::BoneTransforms;
use posereg::joints::joint::rotation_degrees;
use posereg::labels as label;
use posereg::phantom::{generate, PhantomSize, PhantomSpec};
use posereg::pipeline::inputs::{Pair, PairPaths};
use posereg::pipeline::register::RegisterOptions;
use posereg::registration::{Registered, Request};
use posereg::report::evaluate::field_error;
use posereg::{Field, Labels};
use std::path::{Path, PathBuf};

/// Arguments of `posereg demo`.
#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(short, long, default_value = "posereg-demo")]
    pub output: PathBuf,
    /// Phantom grid.
    #[arg(long, value_enum, default_value_t = PhantomSize::Half)]
    pub size: PhantomSize,
    /// Flexion of the target (degrees).
    #[arg(long, default_value_t = 30.0)]
    pub flexion: f64,
    /// Skip the articulated initialisation (the paper's first experiment, small bends).
    #[arg(long)]
    pub no_init: bool,
    /// Registration settings file (.toml or .json), as for `posereg register`.
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Makes the pair, registers it, prints the figures and where the outputs are.
pub fn run(args: &DemoArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let mut options = match &args.config {
        Some(path) => load_options(path)?,
        None => RegisterOptions::default(),
    };
    options.initialise &= !args.no_init;
    let _folder = posereg::io::prepare_output_folder(&args.output)?;
    let (opened, line) = open_backend(device)?;
    reporter.say(&line);
    let spec = |flexion_degrees, seed| PhantomSpec {
        size: args.size,
        flexion_degrees,
        seed,
        ..Default::default()
    };
    reporter.result(&format!(
        "making a {:?} knee phantom straight and bent {}° ...",
        args.size, args.flexion
    ));
    let source = generate(&spec(0.0, 1))?;
    let target = generate(&spec(args.flexion, 2))?;
    let truth = (target.truth_field, target.truth, target.labels);
    let pair = Pair {
        source: source.image,
        labels: source.labels,
        target: target.image,
        warnings: Vec::new(),
    };
    reporter.result("registering ...");
    let request = Request {
        pair: &pair,
        names: PairPaths {
            source: Path::new("the straight phantom"),
            labels: Path::new("the straight phantom's labels"),
            target: Path::new("the bent phantom"),
        },
        options: &options,
        start: None,
        target_mask: None,
        side: None,
        inputs: serde_json::json!({
            "phantom": format!("{:?}, straight and bent {}°", args.size, args.flexion),
            "start": posereg::init::articulated::Start::describe(None),
        }),
        keep_initial_field: true,
    };
    let done = posereg::registration::register_pair(&opened, request, reporter)?;
    let out = |name: &str| args.output.join(name);
    save_volume(&out("source.nii.gz"), &pair.source, DataType::F32)?;
    save_labels(&out("source_labels.nii.gz"), &pair.labels)?;
    save_volume(&out("target.nii.gz"), &pair.target, DataType::F32)?;
    save_field(&out("truth_field.nii.gz"), &truth.0)?;
    truth.1.save(&out("truth.json"))?;
    write_registration(&args.output, (&pair, &options), &done, reporter)?;
    reporter.result(&format!(
        "done in {:.1} s on {}",
        done.seconds,
        opened.describe()
    ));
    say_bone_errors(&done, &truth.1, reporter);
    say_field_errors(&pair, &done, (&truth.0, &truth.2), reporter)?;
    reporter.result(&format!(
        "outputs in {}: what `posereg register` writes (warped.nii.gz, field.nii.gz, \
         inverse_field.nii.gz, jacobian.nii.gz, transform.json, bones/*.tfm, report.json, \
         quicklook.png), the inputs and the truth",
        args.output.display()
    ));
    reporter.save_log(&args.output.join("posereg.log"))?;
    Ok(())
}

/// Prints each bone's motion against the truth.
fn say_bone_errors(done: &Registered, truth: &BoneTransforms, reporter: &Reporter) {
    let motions = (done.result.init.as_ref())
        .map(|i| i.motions.clone())
        .unwrap_or_default();
    if !motions.is_empty() {
        reporter.result("bone motions against the truth:");
    }
    for (code, m) in &motions {
        let truth = truth
            .bones
            .iter()
            .find(|t| t.label == *code)
            .map(|t| t.affine());
        if let Some(truth) = truth {
            let angle = rotation_degrees(&(m.try_inverse().unwrap_or(*m) * truth));
            let shift = (m.fixed_view::<3, 1>(0, 3) - truth.fixed_view::<3, 1>(0, 3)).norm();
            reporter.result(&format!(
                "  {:<8} rotation error {angle:.2}°, translation difference {shift:.2} mm",
                bone_name(*code)
            ));
        }
    }
}

/// Prints the field's error against the truth inside the body, where both scans see it (the
/// bent shank brings in anatomy the straight scan never saw), before, after the
/// initialisation and after the registration, and the field's figures.
fn say_field_errors(
    pair: &Pair,
    done: &Registered,
    (truth_field, target_labels): (&Field, &Labels),
    reporter: &Reporter,
) -> anyhow::Result<()> {
    let seen = posereg::report::evaluate::seen_by_both(truth_field, &pair.source.grid, 0.0);
    let body = |n: usize| target_labels.data[n] != label::OUTSIDE && seen[n];
    let zero = posereg::Image::filled(pair.target.grid.clone(), [0.0f32; 3]);
    let before = field_error(&zero, truth_field, body)?;
    let after = field_error(&done.result.field, truth_field, body)?;
    if let Some(initial_field) = &done.initial_field {
        let initial = field_error(initial_field, truth_field, body)?;
        reporter.result(&format!(
            "after the articulated initialisation: mean error {:.2} mm, within 2 voxels {:.1}%",
            initial.mean_mm,
            100.0 * initial.within_2_voxels
        ));
    }
    reporter.result(&format!(
        "inside the body, where both scans see it ({} voxels):",
        after.voxels
    ));
    reporter.result(&format!(
        "  mean error      {:.2} mm -> {:.2} mm   (within 2 voxels {:.1}% -> {:.1}%, within 4 {:.1}% -> {:.1}%)",
        before.mean_mm,
        after.mean_mm,
        100.0 * before.within_2_voxels,
        100.0 * after.within_2_voxels,
        100.0 * before.within_4_voxels,
        100.0 * after.within_4_voxels
    ));
    let correlations = &done.report.correlations;
    reporter.result(&format!(
        "  correlation     {:.3} -> {:.3}   (over the target's body)",
        correlations.before, correlations.after
    ));
    let result = &done.result;
    let free = result.adaptive.points.iter().filter(|p| !p.pinned).count();
    reporter.result(&format!(
        "  control points  {free} adaptive + {} pinned on bone surfaces; Jacobian min {:.3}, {:.4}% folded",
        result.adaptive.points.len() - free,
        result.min_jacobian,
        100.0 * result.folded_share
    ));
    Ok(())
}
