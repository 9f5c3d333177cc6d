//! `posereg init --source S --source-labels L --target T -o DIR`: the articulated
//! initialisation alone (per-bone rigid, skinning weights, volume skeletal deformation).

use super::BlendingFlag;
use clap::Args;
use posereg::device::DeviceWanted;
use posereg::init::articulated::InitOptions;
use posereg::io::config::load_options;
use posereg::jobs::initialise::initialise_files;
use posereg::jobs::register::PairFiles;
use posereg::jobs::reporter::Reporter;
use posereg::joints::anatomy::Side;
use posereg::joints::chain::{self, Link};
use posereg::pipeline::register::RegisterOptions;
use std::path::PathBuf;

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
    pub blending: Option<BlendingFlag>,
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
    /// The files and folder, for the library's jobs.
    pub fn files(&self) -> PairFiles {
        PairFiles {
            source: self.source.clone(),
            labels: self.source_labels.clone(),
            target: self.target.clone(),
            output: self.output.clone(),
            side: self.side,
        }
    }
}

/// `options` with the kinematic chain's codes those of --label-map, when given, checked.
pub fn with_label_map(
    mut options: RegisterOptions,
    map: &Option<Vec<(String, u16)>>,
) -> anyhow::Result<RegisterOptions> {
    options.init.chain = relabelled(&options.init.chain, map)?;
    options.check()?;
    Ok(options)
}

/// `chain` with the codes of --label-map, when given.
fn relabelled(chain: &[Link], map: &Option<Vec<(String, u16)>>) -> anyhow::Result<Vec<Link>> {
    Ok(match map {
        Some(map) => chain::relabelled(chain, map)?,
        None => chain.to_vec(),
    })
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
            options.blending = blending.into();
        }
        if let Some(reach) = &self.reach {
            options.reach = reach.clone();
        }
        options.chain = relabelled(&options.chain, &self.pair.label_map)?;
        options.check()?;
        Ok(options)
    }
}

/// Runs the initialisation and writes init.json, init_field.nii.gz, initialised.nii.gz.
pub fn run(args: &InitArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let options = args.options()?;
    let given = args.init.as_deref();
    initialise_files(&args.pair.files(), &options, given, device, reporter)?;
    Ok(())
}
