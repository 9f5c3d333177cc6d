//! `posereg series --source S --source-labels L --targets T1 T2 ... -o DIR`: one labelled scan
//! and the same knee in several poses, each registered as `register` would, in pose order
//! (posereg::jobs::series says how); a series stopped part way resumes when run again.

use super::init::with_label_map;
use super::settings::SettingsArgs;
use clap::Args;
use posereg::device::DeviceWanted;
use posereg::jobs::reporter::Reporter;
use posereg::jobs::series::{register_series, SeriesFiles};
use posereg::joints::anatomy::Side;
use std::path::PathBuf;

/// Arguments of `posereg series`.
#[derive(Args, Debug)]
pub struct SeriesArgs {
    /// Source (moving) image: the scan with bone labels.
    #[arg(long, visible_alias = "moving")]
    pub source: PathBuf,
    /// Bone labels of the source, on its grid.
    #[arg(long, visible_alias = "moving-labels")]
    pub source_labels: PathBuf,
    /// The other poses (fixed images), in pose order: each is registered after the one before.
    #[arg(long, num_args = 1.., required = true)]
    pub targets: Vec<PathBuf>,
    /// Output folder: one folder per pose and series.csv.
    #[arg(short, long)]
    pub output: PathBuf,
    /// --config, --dense, --no-dense, as `register` takes.
    #[command(flatten)]
    pub settings: SettingsArgs,
    /// The codes of the bones in your label map, as `register` takes.
    #[arg(long, value_delimiter = ',', value_parser = super::init::bone_code)]
    pub label_map: Option<Vec<(String, u16)>>,
    /// Which knee, for the kinematics (default: from the labels' fibula).
    #[arg(long, value_enum)]
    pub side: Option<Side>,
    /// Register each pose from the source with the previous pose's bone motions tried first,
    /// instead of reaching it through the previous pose (its labels carried there, the bones
    /// registered from it and the fields composed).
    #[arg(long)]
    pub unchained: bool,
}

/// Registers every pose not yet finished in order and writes series.csv (posereg::jobs::series).
pub fn run(args: &SeriesArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let options = with_label_map(args.settings.options()?, &args.label_map)?;
    let files = SeriesFiles {
        source: args.source.clone(),
        labels: args.source_labels.clone(),
        targets: args.targets.clone(),
        output: args.output.clone(),
        side: args.side,
        chained: !args.unchained,
    };
    register_series(&files, &options, device, reporter)?;
    Ok(())
}
