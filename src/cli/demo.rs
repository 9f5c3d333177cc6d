//! `posereg demo [-o DIR] [--size half] [--flexion 60]`: a phantom pair made on the spot and
//! registered (articulated initialisation, then adaptive cubic-RBF), with its figures
//! against the known truth.

use super::init::kinematics;
use super::outputs::write_registration;
use super::progress::Reporter;
use clap::Args;
use posereg::device::{open_backend, DeviceWanted};
use posereg::init::articulated::bone_name;
use posereg::io::config::load_options;
use posereg::io::field::save_field;
use posereg::io::nifti::{save_labels, save_volume, DataType};
use posereg::joints::joint::rotation_degrees;
use posereg::labels as label;
use posereg::phantom::{generate, PhantomSize, PhantomSpec};
use posereg::pipeline::register::{register_observed, Inputs, RegisterOptions};
use posereg::report::evaluate::field_error;
use posereg::report::Run;
use std::path::PathBuf;

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
    let source = generate(&posereg::cpu::CpuBackend, &spec(0.0, 1))?;
    let target = generate(&posereg::cpu::CpuBackend, &spec(args.flexion, 2))?;
    reporter.result("registering ...");
    let started = std::time::Instant::now();
    // The initial field, brought back for its error against the truth.
    let mut initial_field = None;
    let result = posereg::on_backend!(opened, backend => register_observed(
        backend,
        Inputs::new(&source.image, &source.labels, &target.image),
        &options,
        reporter,
        &mut |images| {
            initial_field = Some(images.field.download_field(backend)?);
            Ok(())
        },
    ))?;
    let seconds = started.elapsed().as_secs_f64();

    let out = |name: &str| args.output.join(name);
    save_volume(&out("source.nii.gz"), &source.image, DataType::F32)?;
    save_labels(&out("source_labels.nii.gz"), &source.labels)?;
    save_volume(&out("target.nii.gz"), &target.image, DataType::F32)?;
    save_field(&out("truth_field.nii.gz"), &target.truth_field)?;
    target.truth.save(&out("truth.json"))?;
    let run = Run {
        source: &source.image,
        labels: &source.labels,
        target: &target.image,
        result: &result,
        options: &options,
        inputs: serde_json::json!({
            "phantom": format!("{:?}, straight and bent {}°", args.size, args.flexion),
            "start": posereg::init::articulated::Start::describe(None),
        }),
        warnings: &[],
        seconds,
        kinematics: match &result.init {
            Some(init) => {
                let chain = &options.init.chain;
                kinematics(None, &source.labels, chain, init, reporter)?
            }
            None => None,
        },
    };
    let (correlations, _) = write_registration(&args.output, &opened, &run, reporter)?;
    reporter.result(&format!("done in {seconds:.1} s on {}", opened.describe()));
    let motions = result
        .init
        .as_ref()
        .map(|i| i.motions.clone())
        .unwrap_or_default();
    if !motions.is_empty() {
        reporter.result("bone motions against the truth:");
    }
    for (code, m) in &motions {
        let truth = target
            .truth
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
    // Inside the body and seen by both scans: where the true source point lies in the source's
    // field of view (the bent shank brings in anatomy the straight scan never saw).
    let seen =
        posereg::report::evaluate::seen_by_both(&target.truth_field, &source.image.grid, 0.0);
    let body = |n: usize| target.labels.data[n] != label::OUTSIDE && seen[n];
    let zero = posereg::Image::filled(target.image.grid.clone(), [0.0f32; 3]);
    let before = field_error(&zero, &target.truth_field, body)?;
    let after = field_error(&result.field, &target.truth_field, body)?;
    if let Some(initial_field) = &initial_field.filter(|_| result.init.is_some()) {
        let initial = field_error(initial_field, &target.truth_field, body)?;
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
    reporter.result(&format!(
        "  correlation     {:.3} -> {:.3}   (over the target's body)",
        correlations.before, correlations.after
    ));
    let free = result.adaptive.points.iter().filter(|p| !p.pinned).count();
    reporter.result(&format!(
        "  control points  {free} adaptive + {} pinned on bone surfaces; Jacobian min {:.3}, {:.4}% folded",
        result.adaptive.points.len() - free,
        result.min_jacobian,
        100.0 * result.folded_share
    ));
    reporter.result(&format!(
        "outputs in {}: what `posereg register` writes (warped.nii.gz, field.nii.gz, \
         inverse_field.nii.gz, jacobian.nii.gz, transform.json, bones/*.tfm, report.json, \
         quicklook.png), the inputs and the truth",
        args.output.display()
    ));
    reporter.save_log(&args.output.join("posereg.log"))?;
    Ok(())
}
