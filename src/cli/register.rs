//! `posereg register --source S --source-labels L --target T -o DIR [--no-init]`: the whole
//! pipeline, writing warped.nii.gz, field.nii.gz, inverse_field.nii.gz, transform.json,
//! bones/*.tfm, jacobian.nii.gz, report.json and quicklook.png.

use super::init::{with_label_map, PairArgs};
use super::settings::SettingsArgs;
use super::BlendingFlag;
use clap::Args;
use posereg::device::DeviceWanted;
use posereg::images::similarity::Similarity;
use posereg::io::config::options_toml;
use posereg::jobs::register::{register_files, RegisterFiles, StartOf};
use posereg::jobs::reporter::Reporter;
use posereg::levels::PerLevel;
use posereg::pipeline::register::RegisterOptions;
use std::path::PathBuf;

/// Arguments of `posereg register`.
#[derive(Args, Debug)]
#[command(after_help = settings_help())]
pub struct RegisterArgs {
    /// The inputs and the output folder.
    #[command(flatten)]
    pub pair: PairArgs,
    /// --config, --dense, --no-dense.
    #[command(flatten)]
    pub settings: SettingsArgs,
    /// Skip the articulated initialisation (the paper's first experiment: small bends only).
    #[arg(long)]
    pub no_init: bool,
    /// Bone labels to use, e.g. 2,3,4 (default: every bone label present).
    #[arg(long, value_delimiter = ',')]
    pub bones: Option<Vec<u16>>,
    /// How the bone motions are blended across the soft tissue (init.blending).
    #[arg(long, value_enum)]
    pub blending: Option<BlendingFlag>,
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
        "Settings (config file keys; unknown keys are refused) and their defaults. Values that \
         vary by pyramid level are written coarse to fine (\"100x60x30\"); those shown as one \
         number take one value for every level or one per level. Where `levels` differs from \
         the number of values a default has, the default is read from its finest level up \
         (levels beyond its values repeat its coarsest):\n\n{}",
        options_toml(&RegisterOptions::default())
    )
}

impl RegisterArgs {
    /// Defaults, overridden by the config file, overridden by the flags.
    pub fn options(&self) -> anyhow::Result<RegisterOptions> {
        let mut options = self.settings.options()?;
        if self.no_init {
            options.initialise = false;
        }
        if let Some(bones) = &self.bones {
            options.init.bones = bones.clone();
        }
        if let Some(blending) = self.blending {
            options.init.blending = blending.into();
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
        with_label_map(options, &self.pair.label_map)
    }
}

/// Runs the registration and writes its outputs.
pub fn run(args: &RegisterArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let options = args.options()?;
    let files = RegisterFiles {
        pair: args.pair.files(),
        target_mask: args.target_mask.clone(),
        init: args.init.clone(),
    };
    let identity: StartOf = &|_, _| Ok(None);
    let opened = (device, &mut None);
    let written = register_files(&files, &options, opened, (None, identity), reporter)?;
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

#[cfg(test)]
mod tests {
    use crate::cli::{Cli, Command};
    use clap::Parser;

    /// `posereg register` with the four path arguments and `flags`, parsed into its options.
    fn options_with(flags: &[&str]) -> posereg::pipeline::register::RegisterOptions {
        let paths = [
            "--source",
            "s",
            "--source-labels",
            "l",
            "--target",
            "t",
            "-o",
            "o",
        ];
        let line = [&["posereg", "register"][..], &paths, flags].concat();
        match Cli::try_parse_from(line).unwrap().command {
            Command::Register(args) => args.options().unwrap(),
            other => panic!("parsed as {other:?}"),
        }
    }

    #[test]
    fn each_flag_reaches_the_options() {
        let defaults = options_with(&[]);
        assert!(defaults.initialise && defaults.dense.enabled && defaults.dense.levels == 3);
        assert!(!options_with(&["--no-init"]).initialise);
        assert!(!options_with(&["--no-dense"]).dense.enabled);
        // --dense over a settings file that turns the stage off.
        let dir = tempfile::tempdir().unwrap();
        let off = dir.path().join("off.toml");
        std::fs::write(&off, "[dense]\nenabled = false\nstep_mm = 1.5\n").unwrap();
        let off = off.to_str().unwrap();
        assert!(!options_with(&["--config", off]).dense.enabled);
        let on = options_with(&["--config", off, "--dense"]).dense;
        assert!(on.enabled && on.step_mm == 1.5, "{on:?}");
    }
}
