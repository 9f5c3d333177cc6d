//! `posereg register --source S --source-labels L --target T -o DIR [--no-init]`: the whole
//! pipeline, writing warped.nii.gz, field.nii.gz, inverse_field.nii.gz, transform.json,
//! bones/*.tfm, jacobian.nii.gz, report.json and quicklook.png.

use super::init::PairArgs;
use super::outputs::write_registration;
use super::progress::Reporter;
use clap::Args;
use posereg::abi::Blending;
use posereg::device::{open_backend, DeviceWanted, Opened};
use posereg::images::similarity::Similarity;
use posereg::init::articulated::{Chained, Start};
use posereg::io::config::{load_options, options_toml};
use posereg::io::transform::BoneTransforms;
use posereg::levels::PerLevel;
use posereg::pipeline::inputs::{load_given_motions, load_target_mask, Pair};
use posereg::pipeline::register::RegisterOptions;
use posereg::registration::{file_inputs, Registered, Request};
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
    /// Run the dense refinement after the adaptive stage (dense.enabled = true).
    #[arg(long, conflicts_with = "no_dense")]
    pub dense: bool,
    /// Skip the dense refinement (dense.enabled = false), whatever the settings file says.
    #[arg(long)]
    pub no_dense: bool,
    /// Bone labels to use, e.g. 2,3,4 (default: every bone label present).
    #[arg(long, value_delimiter = ',')]
    pub bones: Option<Vec<u16>>,
    /// How the bone motions are blended across the soft tissue (init.blending).
    #[arg(long, value_enum)]
    pub blending: Option<Blending>,
    /// How far a small bone's tissue reaches, e.g. 1,1.5,2 (init.reach): several rising limits
    /// are tried and the limit where the fit to the target peaks kept; one fixes it.
    #[arg(long, value_delimiter = ',')]
    pub reach: Option<Vec<f64>>,
    /// Adaptive stage: L-BFGS iterations per refinement, per level coarse to fine, e.g. 40x30x20.
    #[arg(long)]
    pub iterations: Option<PerLevel<usize>>,
    /// Adaptive stage: cells whose residual exceeds this multiple of the mean get a control
    /// point, per level coarse to fine (default 8x8x4: 4 at the finest level, 8 above).
    #[arg(long)]
    pub threshold: Option<PerLevel<f64>>,
    /// Adaptive stage: the image term per level coarse to fine, ssd or lncc (local normalised
    /// cross-correlation, for scans whose shading or contrast differ), e.g. ssdxssdxlncc.
    #[arg(long)]
    pub similarity: Option<PerLevel<Similarity>>,
    /// Mask on the target's grid: only its non-zero voxels count as evidence for the
    /// non-rigid stage (leave out another limb, an artefact, the edge of the coil).
    #[arg(long, visible_alias = "fixed-mask")]
    pub target_mask: Option<PathBuf>,
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
    pub fn options(&self) -> anyhow::Result<RegisterOptions> {
        let mut options = match &self.config {
            Some(path) => load_options(path)?,
            None => RegisterOptions::default(),
        };
        if self.no_init {
            options.initialise = false;
        }
        if self.dense || self.no_dense {
            options.dense.enabled = self.dense;
        }
        if let Some(bones) = &self.bones {
            options.init.bones = bones.clone();
        }
        if let Some(blending) = self.blending {
            options.init.blending = blending;
        }
        if let Some(reach) = &self.reach {
            options.init.reach = reach.clone();
        }
        if let Some(iterations) = &self.iterations {
            options.adaptive.iterations = iterations.clone();
        }
        if let Some(threshold) = &self.threshold {
            options.adaptive.threshold = threshold.clone();
        }
        if let Some(similarity) = &self.similarity {
            options.adaptive.similarity = similarity.clone();
        }
        options.init.chain = self.pair.chain(&options.init.chain)?;
        options.check()?;
        Ok(options)
    }
}

/// Runs the registration and writes its outputs.
pub fn run(args: &RegisterArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let options = args.options()?;
    let unchained: StartOf = &|_, _| Ok(None);
    let starts = (None, unchained);
    let written = register_pair(args, &options, (device, &mut None), starts, reporter)?;
    let failed = written.registered.failed_checks();
    if args.strict && !failed.is_empty() {
        anyhow::bail!(
            "--strict: {} result check(s) failed ({}); the outputs are in {} for inspection",
            failed.len(),
            failed.join(", "),
            args.pair.output.display()
        );
    }
    Ok(())
}

/// What one registration leaves for its caller once its outputs are written.
pub struct Written {
    /// The registration and what came with it.
    pub registered: Registered,
    /// The bone motions (none without the initialisation).
    pub transforms: BoneTransforms,
    /// report.json's headline figures, for a summary over several registrations.
    pub summary: serde_json::Value,
}

/// Where the bones' registration of a loaded pair starts: `posereg series` works it out from
/// the pair and the backend (its previous pose), `register` starts from the identity.
pub type StartOf<'s> = &'s dyn Fn(&Opened, &Pair) -> anyhow::Result<Option<Chained>>;

/// Loads the pair `args` names, registers it with `options` on the backend `opened` holds
/// (opening the one `device` asks for the first time), and writes every output into its
/// folder. The bones start from `args`' given motions, else from a chained pose `chained`
/// makes, else from `seeds` tried first, else from the identity.
pub fn register_pair(
    args: &RegisterArgs,
    options: &RegisterOptions,
    (device, opened): (&DeviceWanted, &mut Option<Opened>),
    (seeds, chained): (Option<&BoneTransforms>, StartOf),
    reporter: &Reporter,
) -> anyhow::Result<Written> {
    let (_folder, pair) = args.pair.load(reporter, &options.init.chain)?;
    let given = match &args.init {
        Some(path) => Some(load_given_motions(path, &pair.labels, &options.init)?),
        None => None,
    };
    let mask = match &args.target_mask {
        Some(path) => Some(load_target_mask(
            path,
            &pair.target.grid,
            &args.pair.target,
        )?),
        None => None,
    };
    if opened.is_none() {
        let (backend, line) = open_backend(device)?;
        reporter.say(&line);
        *opened = Some(backend);
    }
    let opened = opened.as_ref().expect("opened above");
    let chained = chained(opened, &pair)?;
    let start = (given.as_ref().map(Start::Given))
        .or(chained.as_ref().map(Start::Chained))
        .or(seeds.map(Start::Seeded));
    let request = Request {
        pair: &pair,
        names: args.pair.paths(),
        options,
        start,
        target_mask: mask.as_ref(),
        side: args.pair.side,
        inputs: file_inputs(
            args.pair.paths(),
            (args.init.as_deref(), args.target_mask.as_deref()),
            start,
        ),
        keep_initial_field: false,
    };
    let registered = posereg::registration::register_pair(opened, request, reporter)?;
    write_registration(&args.pair.output, (&pair, options), &registered, reporter)?;
    let summary = summary(args, start, &registered);
    reporter.result(&format!(
        "registered in {:.1} s: correlation {:.3} -> {:.3}, {} control points, Jacobian min {:.3}; outputs in {}",
        registered.seconds,
        registered.report.correlations.before,
        registered.report.correlations.after,
        registered.result.adaptive.points.len(),
        registered.result.min_jacobian,
        args.pair.output.display()
    ));
    reporter.save_log(&args.pair.output.join("posereg.log"))?;
    Ok(Written {
        transforms: registered.result.transforms(options),
        registered,
        summary,
    })
}

/// report.json's headline figures for a summary over several registrations (series.json).
fn summary(args: &RegisterArgs, start: Option<Start>, done: &Registered) -> serde_json::Value {
    let correlations = &done.report.correlations;
    serde_json::json!({
        "folder": args.pair.output,
        "target": args.pair.target,
        "start": Start::describe(start),
        "seconds": done.seconds,
        "correlation": { "before": correlations.before, "after": correlations.after },
        "control_points": done.result.adaptive.points.len(),
        "jacobian_min": done.result.min_jacobian,
        "checks_failed": done.failed_checks(),
    })
}
