//! `posereg register --source S --source-labels L --target T -o DIR [--no-init]`: the whole
//! pipeline, writing warped.nii.gz, field.nii.gz, transform.json, jacobian.nii.gz,
//! report.json and quicklook.png.

use super::init::{load_given, PairArgs};
use super::progress::Reporter;
use clap::Args;
use posereg::abi::Blending;
use posereg::device::{open_backend, DeviceWanted};
use posereg::inputs::{check_settings, Pair};
use posereg::io::config::{load_options, options_toml};
use posereg::io::field::save_field;
use posereg::io::itk_transform::save_bone_tfms;
use posereg::io::nifti::{save_volume, DataType};
use posereg::levels::PerLevel;
use posereg::metric::correlation;
use posereg::register::{register, unregistered, Inputs, RegisterOptions};
use posereg::result_checks::{result_checks, Check, Correlations};
use posereg::Error;
use std::path::PathBuf;

/// Arguments of `posereg register`.
#[derive(Args, Debug)]
#[command(after_help = settings_help())]
pub struct RegisterArgs {
    /// The inputs and the output folder.
    #[command(flatten)]
    pub pair: PairArgs,
    /// Settings file (.toml or .json) holding any of the settings listed below; flags given
    /// here override it.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Skip the articulated initialisation (the paper's first experiment: small bends only).
    #[arg(long)]
    pub no_init: bool,
    /// Bone labels to use, e.g. 2,3,4 (default: every bone label present).
    #[arg(long, value_delimiter = ',')]
    pub bones: Option<Vec<u16>>,
    /// How the bone motions are blended across the soft tissue (init.blending).
    #[arg(long, value_enum)]
    pub blending: Option<Blending>,
    /// Adaptive stage: L-BFGS iterations per refinement, per level coarse to fine, e.g. 40x30x20.
    #[arg(long)]
    pub iterations: Option<PerLevel<usize>>,
    /// Adaptive stage: cells whose residual exceeds this multiple of the mean get a control
    /// point, per level coarse to fine, e.g. 8x8x12.
    #[arg(long)]
    pub threshold: Option<PerLevel<f64>>,
    /// Bone transforms to start from instead of registering the bones (transform.json or
    /// init.json of an earlier run, corrected if need be).
    #[arg(long, conflicts_with = "no_init")]
    pub init: Option<PathBuf>,
    /// Exit non-zero when a result check fails (the field folds, the correlation falls, a
    /// bone's motion lies outside its search); the outputs are still written.
    #[arg(long)]
    pub strict: bool,
}

/// The settings a config file may hold, with their defaults, for --help.
fn settings_help() -> String {
    format!(
        "Settings (config file keys; unknown keys are refused) and their defaults:\n\n{}",
        options_toml(&RegisterOptions::default())
    )
}

impl RegisterArgs {
    /// Defaults, overridden by the config file, overridden by the flags.
    fn options(&self) -> anyhow::Result<RegisterOptions> {
        let mut options = match &self.config {
            Some(path) => load_options(path)?,
            None => RegisterOptions::default(),
        };
        if self.no_init {
            options.initialise = false;
        }
        if let Some(bones) = &self.bones {
            options.init.bones = bones.clone();
        }
        if let Some(blending) = self.blending {
            options.init.blending = blending;
        }
        if let Some(iterations) = &self.iterations {
            options.adaptive.iterations = iterations.clone();
        }
        if let Some(threshold) = &self.threshold {
            options.adaptive.threshold = threshold.clone();
        }
        options.init.chain = self.pair.chain(&options.init.chain)?;
        options.check()?;
        Ok(options)
    }
}

/// The version of report.json's layout: raised when a key changes meaning or goes away.
const REPORT_SCHEMA: u32 = 1;

/// Runs the registration and writes its outputs.
pub fn run(args: &RegisterArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let options = args.options()?;
    let (_folder, pair) = args.pair.load(reporter, &options.init.chain)?;
    check_settings(&options, &pair, args.pair.paths())?;
    let Pair {
        source,
        labels,
        target,
        warnings,
    } = pair;
    let given = match &args.init {
        Some(path) => Some(load_given(path, &labels, &options.init)?),
        None => None,
    };
    let (opened, line) = open_backend(device)?;
    reporter.say(&line);
    let started = std::time::Instant::now();
    let inputs = Inputs {
        given: given.as_ref(),
        ..Inputs::new(&source, &labels, &target)
    };
    let result = posereg::on_backend!(opened, backend => register(
        backend,
        inputs,
        &options,
        reporter,
    ))?;
    let seconds = started.elapsed().as_secs_f64();
    let out = |name: &str| args.pair.output.join(name);
    save_volume(&out("warped.nii.gz"), &result.warped, DataType::F32)?;
    save_field(&out("field.nii.gz"), &result.field)?;
    save_volume(&out("jacobian.nii.gz"), &result.jacobian, DataType::F32)?;
    let transform = result.transforms(&options);
    transform.save(&out("transform.json"))?;
    save_bone_tfms(&args.pair.output, &transform)?;
    let before =
        posereg::on_backend!(opened, backend => unregistered(backend, &source, &target.grid))?;
    let body = |n: usize| target.data[n] > 0.0;
    let correlations = Correlations {
        before: correlation(&before.data, &target.data, body),
        after: correlation(&result.warped.data, &target.data, body),
    };
    let checks = result_checks(&result, correlations, &options);
    let finished = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let report = serde_json::json!({
        "schema": REPORT_SCHEMA,
        "posereg": env!("CARGO_PKG_VERSION"),
        "command_line": std::env::args().collect::<Vec<_>>(),
        "finished_unix_seconds": finished,
        "device": opened.describe(),
        "seconds": seconds,
        "inputs": { "source": args.pair.source, "source_labels": args.pair.source_labels, "target": args.pair.target },
        "options": options,
        "initialisation": result.init.as_ref().map(|i| serde_json::json!({
            "bones": i.reports,
            "fold_repair": i.repair,
        })),
        "adaptive_stages": result.adaptive.stages,
        "control_points": result.adaptive.points.len(),
        "correlation": {
            "before": correlations.before,
            "after": correlations.after,
            "over": "the target's voxels above 0 (its body), source resampled without and with the field",
        },
        "jacobian": { "min": result.min_jacobian, "folded_share": result.folded_share, "unfolding": result.unfolding },
        "device_traffic": { "stages": result.traffic, "evaluations": result.adaptive.evaluations },
        "checks": checks,
        "warnings": warnings,
    });
    let centre = match &result.init {
        Some(init) => [init.axis.point.x, init.axis.point.y, init.axis.point.z],
        None => target
            .grid
            .voxel_to_world(target.grid.dims.map(|d| (d as f64 - 1.0) / 2.0)),
    };
    posereg::quicklook::save(
        &out("quicklook.png"),
        &target,
        &before,
        &result.warped,
        &result.adaptive.points,
        centre,
    )?;
    let text = serde_json::to_string_pretty(&report)?;
    posereg::io::write_atomically(&out("report.json"), |tmp| {
        std::fs::write(tmp, text + "\n").map_err(|e| Error::io(tmp, e))
    })?;
    println!(
        "registered in {seconds:.1} s: correlation {:.3} -> {:.3}, {} control points, Jacobian min {:.3}; outputs in {}",
        correlations.before,
        correlations.after,
        result.adaptive.points.len(),
        result.min_jacobian,
        args.pair.output.display()
    );
    let failed: Vec<&Check> = checks.iter().filter(|c| !c.passed).collect();
    for check in &failed {
        reporter.warn(&format!("check {} failed: {}", check.name, check.detail));
    }
    if args.strict && !failed.is_empty() {
        let names: Vec<&str> = failed.iter().map(|c| c.name).collect();
        anyhow::bail!(
            "--strict: {} result check(s) failed ({}); the outputs are in {} for inspection",
            failed.len(),
            names.join(", "),
            args.pair.output.display()
        );
    }
    Ok(())
}
