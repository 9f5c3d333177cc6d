//! `posereg init --source S --source-labels L --target T -o DIR`: the articulated
//! initialisation alone (per-bone rigid, skinning weights, volume skeletal deformation).

use super::outputs::write_kinematics;
use super::progress::Reporter;
use clap::Args;
use posereg::abi::Blending;
use posereg::abi::Interpolation;
use posereg::backend::resample_volume;
use posereg::device::{open_backend, DeviceWanted, Opened};
use posereg::images::metric::correlation;
use posereg::init::articulated::{
    initialise_volumes, rigid_field, InitOptions, InitialVolumes, Initialisation, Start,
};
use posereg::io::config::load_options;
use posereg::io::field::save_field;
use posereg::io::itk_transform::save_bone_tfms;
use posereg::io::nifti::{save_volume, DataType};
use posereg::io::{prepare_output_folder, OutputFolder};
use posereg::joints::anatomy::Side;
use posereg::joints::chain::{self, Link};
use posereg::joints::joint::rotation_degrees;
use posereg::joints::kinematics::KneeKinematics;
use posereg::pipeline::inputs::{check_bones, load_given_motions, load_pair, Pair, PairPaths};
use posereg::pipeline::register::{unregistered, RegisterOptions};
use posereg::Volume;
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
    /// How far a small bone's tissue reaches, e.g. 1,1.5,2 (init.reach): several rising limits
    /// are tried and the limit where the fit to the target peaks kept; one fixes it.
    #[arg(long, value_delimiter = ',')]
    pub reach: Option<Vec<f64>>,
    /// Bone transforms to start from instead of registering (bone-transform JSON).
    #[arg(long)]
    pub init: Option<PathBuf>,
}

/// The straight scan with its bone labels, the bent scan, and where outputs go: what `init`
/// and `register` both take.
#[derive(Args, Debug)]
pub struct PairArgs {
    /// Source (moving) image: the scan with bone labels, e.g. the straight knee.
    #[arg(long, visible_alias = "moving")]
    pub source: PathBuf,
    /// Bone labels of the source, on its grid (2 femur, 3 tibia, 4 patella, 5 fibula unless
    /// --label-map says otherwise).
    #[arg(long, visible_alias = "moving-labels")]
    pub source_labels: PathBuf,
    /// Target (fixed) image: the other pose; outputs are on its grid.
    #[arg(long, visible_alias = "fixed")]
    pub target: PathBuf,
    /// Output folder (created if missing).
    #[arg(short, long)]
    pub output: PathBuf,
    /// The codes of the bones in your label map, e.g. femur=1,tibia=3,patella=5: bones it
    /// does not name are not registered, other codes are soft tissue.
    #[arg(long, value_delimiter = ',', value_parser = bone_code)]
    pub label_map: Option<Vec<(String, u16)>>,
    /// Which knee, for kinematics.json (default: read from the labels, the fibula lying
    /// lateral to the tibia).
    #[arg(long, value_enum)]
    pub side: Option<Side>,
}

/// One `name=code` of --label-map.
pub fn bone_code(text: &str) -> Result<(String, u16), String> {
    let (name, code) = text
        .split_once('=')
        .ok_or_else(|| format!("{text:?} is not name=code (e.g. femur=1)"))?;
    let code = code
        .trim()
        .parse::<u16>()
        .map_err(|_| format!("{code:?} in {text:?} is not a label code (0 to 65535)"))?;
    Ok((name.trim().to_string(), code))
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

    /// `chain` with the codes of --label-map, when given.
    pub fn chain(&self, chain: &[Link]) -> anyhow::Result<Vec<Link>> {
        Ok(match &self.label_map {
            Some(map) => chain::relabelled(chain, map)?,
            None => chain.to_vec(),
        })
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

/// The knee's kinematics for the initialisation's bone motions (see posereg::joints::kinematics),
/// each joint with its bones' confidence, or None with the reason warned.
fn kinematics(
    side: Option<Side>,
    labels: &posereg::Labels,
    chain: &[Link],
    init: &posereg::init::articulated::Initialisation,
    reporter: &Reporter,
) -> anyhow::Result<Option<KneeKinematics>> {
    let (kinematics, warnings) = init.kinematics(labels, chain, side)?;
    warnings.iter().for_each(|w| reporter.warn(w));
    Ok(kinematics)
}

impl InitArgs {
    /// The settings file's `[init]`, overridden by the flags, checked before any voxel is read.
    fn options(&self) -> anyhow::Result<InitOptions> {
        let mut options = match &self.config {
            Some(path) => load_options::<RegisterOptions>(path)?.init,
            None => InitOptions::default(),
        };
        if !self.bones.is_empty() {
            options.bones = self.bones.clone();
        }
        if let Some(blending) = self.blending {
            options.blending = blending;
        }
        if let Some(reach) = &self.reach {
            options.reach = reach.clone();
        }
        options.chain = self.pair.chain(&options.chain)?;
        options.check()?;
        Ok(options)
    }
}

/// Runs the initialisation and writes init.json, init_field.nii.gz, initialised.nii.gz.
pub fn run(args: &InitArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let options = args.options()?;
    let (_folder, pair) = args.pair.load(reporter, &options.chain)?;
    check_bones(&options, &pair.labels, args.pair.paths())?;
    let given = match &args.init {
        Some(path) => Some(load_given_motions(path, &pair.labels, &options)?),
        None => None,
    };
    let (opened, line) = open_backend(device)?;
    reporter.say(&line);
    let started = std::time::Instant::now();
    let (init, images) = posereg::on_backend!(opened, backend => initialise_volumes(
        backend,
        &pair.source,
        &pair.labels,
        &pair.target,
        &options,
        given.as_ref().map(Start::Given),
        reporter,
    ))?;
    let seconds = started.elapsed().as_secs_f64();
    let folder = &args.pair.output;
    write_initialisation(folder, &options, (&init, &images))?;
    let side = args.pair.side;
    if let Some(k) = kinematics(side, &pair.labels, &options.chain, &init, reporter)? {
        write_kinematics(folder, &k, reporter)?;
    }
    reporter.result(&format!("initialisation in {seconds:.1} s"));
    say_bones(&init, &options, reporter);
    say_fit(&opened, &pair, &options, (&init, &images), reporter)?;
    reporter.result(&format!("written to {}", folder.display()));
    reporter.save_log(&folder.join("posereg.log"))?;
    Ok(())
}

/// Writes init.json (the bone motions with the skinning, the flexion axis and each bone's
/// report), the bones' .tfm files, init_field.nii.gz and initialised.nii.gz into `folder`.
fn write_initialisation(
    folder: &Path,
    options: &InitOptions,
    (init, images): (&Initialisation, &InitialVolumes),
) -> anyhow::Result<()> {
    let mut transforms = init.transforms(options);
    transforms.extra.insert(
        "skinning".into(),
        serde_json::json!({
            "method": "shepard inverse-distance",
            "power": posereg::init::skinning::SHEPARD_POWER,
            "reach": init.reach,
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
    transforms.save(&folder.join("init.json"))?;
    save_bone_tfms(folder, &transforms)?;
    save_field(&folder.join("init_field.nii.gz"), &images.field)?;
    let initialised = folder.join("initialised.nii.gz");
    save_volume(&initialised, &images.initialised, DataType::F32)?;
    Ok(())
}

/// Prints each bone's search, fit and confidence, and its rotation.
fn say_bones(init: &Initialisation, options: &InitOptions, reporter: &Reporter) {
    for r in &init.reports {
        let last = r.levels.last();
        reporter.result(&format!(
            "  {:<8} search {:>6}  mean sq. residual {:.1} -> {:.1}; {}",
            r.name,
            r.search_degrees
                .map(|d| format!("{d:.0}°"))
                .unwrap_or("-".into()),
            r.levels.first().map(|l| l.cost_before).unwrap_or(f64::NAN),
            last.map(|l| l.cost_after).unwrap_or(f64::NAN),
            r.confidence.reason
        ));
        for warning in &r.confidence.warnings {
            reporter.warn(warning);
        }
    }
    for (code, m) in &init.motions {
        reporter.result(&format!(
            "  {:<8} rotation {:.2}°",
            options.name_of(*code),
            rotation_degrees(m)
        ));
    }
}

/// Prints the blend's inversion residual, the reach, the folds and the correlation with the
/// target of the source as it lies, moved by the root bone only, and initialised.
fn say_fit(
    opened: &Opened,
    pair: &Pair,
    options: &InitOptions,
    (init, images): (&Initialisation, &InitialVolumes),
    reporter: &Reporter,
) -> anyhow::Result<()> {
    let (source, target) = (&pair.source, &pair.target);
    let residual = &images.residual.data;
    let worst = residual.iter().cloned().fold(0.0f32, f32::max);
    reporter.result(&format!("  blend inversion residual: worst {worst:.3} mm"));
    reporter.result(&format!("  {}", reach_line(&init.reach)));
    let repair = &init.repair;
    reporter.result(&format!(
        "  folds (det J <= 0.05): {} in the blend, {} after {} smoothing rounds and {} unfolding steps",
        repair.folded_before, repair.folded_after, repair.rounds, repair.unfold_steps
    ));
    let body = |n: usize| target.data[n] > 0.0;
    let fit = |moved: &Volume| correlation(&moved.data, &target.data, body);
    let as_it_lies =
        posereg::on_backend!(opened, backend => unregistered(backend, source, &target.grid))?;
    reporter.result(&format!(
        "  correlation with target: identity {:.4}",
        fit(&as_it_lies)
    ));
    let root = (init.motions.iter())
        .find(|m| chain::parent_among(&options.chain, m.0, &init.bones).is_none())
        .map(|m| m.1);
    if let Some(root) = root {
        let root_only = posereg::on_backend!(opened, backend => resample_volume(
            backend,
            source,
            &rigid_field(&root, &target.grid)?,
            0.0,
            Interpolation::Linear,
        ))?;
        reporter.result(&format!(
            "                             root bone only {:.4}",
            fit(&root_only)
        ));
    }
    reporter.result(&format!(
        "                             initialised {:.4}",
        fit(&images.initialised)
    ));
    Ok(())
}

/// How far small segments reach and, when several limits were tried, each one's fit.
fn reach_line(reach: &posereg::init::reach::ReachChoice) -> String {
    let tried: Vec<String> = reach
        .tried
        .iter()
        .map(|t| format!("{} → {:.4}", t.limit, t.local_correlation))
        .collect();
    match tried.is_empty() {
        true => format!("reach limit {} (given)", reach.limit),
        false => format!(
            "reach limit {:.3} (local correlation with the target: {})",
            reach.limit,
            tried.join(", ")
        ),
    }
}
