//! `posereg init --source S --source-labels L --target T -o DIR`: the articulated
//! initialisation alone (per-bone rigid, skinning weights, volume skeletal deformation).

use super::progress::Reporter;
use clap::Args;
use posereg::abi::Blending;
use posereg::abi::Interpolation;
use posereg::articulated::{bone_name, initialise_volumes, rigid_field, InitOptions};
use posereg::backend::resample_volume;
use posereg::chain::{self, Link};
use posereg::device::{open_backend, DeviceChoice};
use posereg::inputs::{check_bones, load_pair, Pair, PairPaths};
use posereg::io::config::load_options;
use posereg::io::field::save_field;
use posereg::io::itk_transform::save_bone_tfms;
use posereg::io::nifti::{save_volume, DataType};
use posereg::io::transform::BoneTransforms;
use posereg::io::{prepare_output_folder, OutputFolder};
use posereg::joint::rotation_degrees;
use posereg::metric::correlation;
use posereg::register::{unregistered, RegisterOptions};
use posereg::Error;
use std::path::{Path, PathBuf};

/// Arguments of `posereg init`.
#[derive(Args, Debug)]
pub struct InitArgs {
    /// The inputs and the output folder.
    #[command(flatten)]
    pub pair: PairArgs,
    /// Bone labels to use, e.g. 2,3,4 (default: every bone label present).
    #[arg(long, value_delimiter = ',')]
    pub bones: Vec<u16>,
    /// Settings file (.toml or .json) as `register` takes; only its `init` settings are used
    /// (the kinematic chain, the follow rules, …). Flags override it.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// How the bone motions are blended across the soft tissue [default: dual-quaternion].
    #[arg(long, value_enum)]
    pub blending: Option<Blending>,
    /// Bone transforms to start from instead of registering (bone-transform JSON).
    #[arg(long)]
    pub init: Option<PathBuf>,
}

/// The straight scan with its bone labels, the bent scan, and where outputs go: what `init`
/// and `register` both take.
#[derive(Args, Debug)]
pub struct PairArgs {
    /// Source (straight pose) image.
    #[arg(long)]
    pub source: PathBuf,
    /// Bone labels of the source (2 femur, 3 tibia, 4 patella, 5 fibula).
    #[arg(long)]
    pub source_labels: PathBuf,
    /// Target (bent pose) image.
    #[arg(long)]
    pub target: PathBuf,
    /// Output folder (created if missing).
    #[arg(short, long)]
    pub output: PathBuf,
}

impl PairArgs {
    /// Where the three inputs are.
    pub fn paths(&self) -> PairPaths<'_> {
        PairPaths {
            source: &self.source,
            labels: &self.source_labels,
            target: &self.target,
        }
    }

    /// Prepares the output folder, then loads and checks the inputs (the labels against the
    /// kinematic chain), printing their warnings.
    pub fn load(
        &self,
        reporter: &Reporter,
        chain: &[Link],
    ) -> anyhow::Result<(OutputFolder, Pair)> {
        let folder = prepare_output_folder(&self.output)?;
        let pair = load_pair(self.paths(), chain)?;
        for warning in &pair.warnings {
            reporter.warn(warning);
        }
        Ok((folder, pair))
    }
}

/// The bone motions of `--init`: rigid, each for a bone present in the labels, and one for
/// every bone `options` registers.
fn load_given(
    path: &Path,
    labels: &posereg::Labels,
    options: &InitOptions,
) -> anyhow::Result<BoneTransforms> {
    let given = BoneTransforms::load(path)?;
    given.check_rigid(path)?;
    let present = chain::present(&options.chain, labels);
    if let Some(b) = given.bones.iter().find(|b| !present.contains(&b.label)) {
        let problem = format!(
            "bone {} ({}) is not among the labels' bones {present:?}",
            b.label, b.name
        );
        return Err(Error::bad_file(path, problem).into());
    }
    if let Some(b) = options
        .bones_in(labels)
        .iter()
        .find(|b| !given.bones.iter().any(|g| g.label == **b))
    {
        return Err(Error::bad_file(path, format!("has no transform for bone label {b}")).into());
    }
    Ok(given)
}

/// Runs the initialisation and writes init.json, init_field.nii.gz, initialised.nii.gz.
pub fn run(args: &InitArgs, device: DeviceChoice, reporter: &Reporter) -> anyhow::Result<()> {
    let mut options = match &args.config {
        Some(path) => load_options::<RegisterOptions>(path)?.init,
        None => InitOptions::default(),
    };
    if !args.bones.is_empty() {
        options.bones = args.bones.clone();
    }
    if let Some(blending) = args.blending {
        options.blending = blending;
    }
    // The flags are checked before any voxel is read.
    options.check()?;
    let (_folder, pair) = args.pair.load(reporter, &options.chain)?;
    let Pair {
        source,
        labels,
        target,
        ..
    } = pair;
    check_bones(&options, &labels, args.pair.paths())?;
    let given = match &args.init {
        Some(path) => Some(load_given(path, &labels, &options)?),
        None => None,
    };
    let (opened, line) = open_backend(device)?;
    reporter.say(&line);
    let started = std::time::Instant::now();
    let (init, images) = posereg::on_backend!(opened, backend => initialise_volumes(
        backend,
        &source,
        &labels,
        &target,
        &options,
        given.as_ref(),
        reporter,
    ))?;
    let seconds = started.elapsed().as_secs_f64();
    let mut transforms = init.transforms();
    transforms.extra.insert(
        "skinning".into(),
        serde_json::json!({
            "method": "shepard inverse-distance",
            "power": posereg::skinning::SHEPARD_POWER,
            "grid_dims": init.weight_grid.dims,
        }),
    );
    transforms.extra.insert(
        "flexion_axis".into(),
        serde_json::json!({
            "point": init.axis.point.as_slice(),
            "direction": init.axis.direction.as_slice(),
        }),
    );
    transforms
        .extra
        .insert("bones_report".into(), serde_json::to_value(&init.reports)?);
    transforms.save(&args.pair.output.join("init.json"))?;
    save_bone_tfms(&args.pair.output, &transforms)?;
    save_field(&args.pair.output.join("init_field.nii.gz"), &images.field)?;
    save_volume(
        &args.pair.output.join("initialised.nii.gz"),
        &images.initialised,
        DataType::F32,
    )?;

    let root = init
        .motions
        .iter()
        .find(|m| chain::parent_among(&options.chain, m.0, &init.bones).is_none())
        .map(|m| m.1);
    let body = |n: usize| target.data[n] > 0.0;
    let corr_identity = correlation(
        &posereg::on_backend!(opened, backend => unregistered(backend, &source, &target.grid))?
            .data,
        &target.data,
        body,
    );
    println!("initialisation in {seconds:.1} s");
    for r in &init.reports {
        let last = r.levels.last();
        println!(
            "  {:<8} search {:>6}  mean sq. residual {:.1} -> {:.1}; {}",
            r.name,
            r.search_degrees
                .map(|d| format!("{d:.0}°"))
                .unwrap_or("-".into()),
            r.levels.first().map(|l| l.cost_before).unwrap_or(f64::NAN),
            last.map(|l| l.cost_after).unwrap_or(f64::NAN),
            r.confidence.reason
        );
        for warning in &r.confidence.warnings {
            reporter.warn(warning);
        }
    }
    for (code, m) in &init.motions {
        println!(
            "  {:<8} rotation {:.2}°",
            bone_name(*code),
            rotation_degrees(m)
        );
    }
    let residual = &images.residual.data;
    let worst = residual.iter().cloned().fold(0.0f32, f32::max);
    println!("  blend inversion residual: worst {worst:.3} mm");
    let repair = &init.repair;
    println!(
        "  folds (det J <= 0.05): {} in the blend, {} after {} smoothing rounds and {} unfolding steps",
        repair.folded_before, repair.folded_after, repair.rounds, repair.unfold_steps
    );
    println!("  correlation with target: identity {corr_identity:.4}");
    if let Some(root) = root {
        let femur_only = posereg::on_backend!(opened, backend => resample_volume(
            backend,
            &source,
            &rigid_field(&root, &target.grid)?,
            0.0,
            Interpolation::Linear,
        ))?;
        println!(
            "                             root bone only {:.4}",
            correlation(&femur_only.data, &target.data, body)
        );
    }
    println!(
        "                             initialised {:.4}",
        correlation(&images.initialised.data, &target.data, body)
    );
    println!("written to {}", args.pair.output.display());
    Ok(())
}
