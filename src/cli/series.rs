//! `posereg series --source S --source-labels L --targets T1 T2 ... -o DIR`: one labelled scan
//! and the same knee in several poses, in pose order. Each pose is registered as `register`
//! would, into DIR/pose_01, DIR/pose_02, …; from the second on, it is reached through the pose
//! before it (posereg::pipeline::series: the bones registered from the source with the previous pose's
//! motions tried first, their step from the previous pose blended there and composed with
//! its field), or with `--unchained` registered from the source with the previous
//! pose's bone motions tried first. DIR/series.csv tabulates every pose's kinematics.
//! DIR/series.json records each pose as it is finished, so a series stopped part way (killed,
//! a pose's target added) resumes where it stopped when run again.

use super::init::PairArgs;
use super::progress::Reporter;
use super::register::{register_pair, RegisterArgs, StartOf};
use clap::Args;
use posereg::device::DeviceWanted;
use posereg::io::config::options_toml;
use posereg::joints::anatomy::Side;
use posereg::pipeline::inputs::{check_settings, load_pair};
use posereg::pipeline::register::RegisterOptions;
use posereg::pipeline::series::{chain_step, Finished};
use posereg::report::quicklook::chart::save_chart;
use posereg::report::series::{FileStamp, MadeFrom, PoseRecord, SeriesFile};
use posereg::volume::Grid;
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
    /// Settings file, as `register` takes.
    #[arg(long)]
    pub config: Option<PathBuf>,
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

impl SeriesArgs {
    /// The output folder of pose `index` (from 0).
    fn folder(&self, index: usize) -> PathBuf {
        self.output.join(format!("pose_{:02}", index + 1))
    }

    /// `register`'s arguments for pose `index` (from 0).
    fn pose(&self, index: usize) -> RegisterArgs {
        RegisterArgs {
            pair: PairArgs {
                source: self.source.clone(),
                source_labels: self.source_labels.clone(),
                target: self.targets[index].clone(),
                output: self.folder(index),
                label_map: self.label_map.clone(),
                side: self.side,
            },
            config: self.config.clone(),
            no_init: false,
            dense: false,
            no_dense: false,
            bones: None,
            blending: None,
            reach: None,
            iterations: None,
            threshold: None,
            similarity: None,
            target_mask: None,
            init: None,
            strict: false,
        }
    }
}

/// Registers every pose not yet finished in order (resuming after the last one an earlier run
/// on the folder finished from the same inputs and settings) and writes series.csv.
pub fn run(args: &SeriesArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let options = args.pose(0).options()?;
    let grids = check_every_pose(args, &options)?;
    let _folder = posereg::io::prepare_output_folder(&args.output)?;
    let targets = (args.targets.iter())
        .map(|t| FileStamp::of(t))
        .collect::<posereg::Result<Vec<_>>>()?;
    let mut series = SeriesFile::finished(&args.output, made_from(args, &options)?, &targets);
    let mut previous = resume(args, &mut series, &grids, reporter);
    let mut opened = None;
    let finished = series.poses.len();
    for (index, target) in targets.iter().enumerate().skip(finished) {
        let pose = args.pose(index);
        reporter.say(&format!(
            "pose {} of {}: {}",
            index + 1,
            args.targets.len(),
            pose.pair.target.display()
        ));
        let chained: StartOf = &|opened, pair| {
            let Some(p) = previous.as_ref().filter(|_| !args.unchained) else {
                return Ok(None);
            };
            let source = (&pair.source, &pair.labels);
            Ok(Some(posereg::on_backend!(opened, backend => chain_step(
                backend, source, p.reached(), &pair.target, &options.init, reporter,
            ))?))
        };
        let seeds = previous.as_ref().map(|p| &p.motions);
        let done = register_pair(
            &pose,
            &options,
            (device, &mut opened),
            (seeds, chained),
            reporter,
        )?;
        let kinematics = done.registered.kinematics.as_ref();
        let pose_of = (index + 1, target.clone());
        (series.poses).push(PoseRecord::new(pose_of, done.summary, kinematics)?);
        series.save(&args.output)?;
        previous = Some(Finished {
            field: done.registered.result.field,
            motions: done.transforms,
        });
    }
    write_summary(args, &series, finished, reporter)
}

/// Writes series.csv and series.png from `series`' records and says what the run did
/// (`kept`: the poses an earlier run had finished).
fn write_summary(
    args: &SeriesArgs,
    series: &SeriesFile,
    kept: usize,
    reporter: &Reporter,
) -> anyhow::Result<()> {
    posereg::io::write_bytes(&args.output.join("series.csv"), series.table())?;
    save_chart(&args.output.join("series.png"), &series.chart())?;
    let beyond = args.folder(args.targets.len());
    if beyond.exists() {
        reporter.warn(&format!(
            "{} and any later pose folder are from an earlier, longer series: they are not part \
             of this one (series.csv and series.json list its {} poses); delete them if unwanted",
            beyond.display(),
            args.targets.len()
        ));
    }
    let kept = match kept {
        0 => String::new(),
        n => format!(" ({n} kept from an earlier run)"),
    };
    reporter.result(&format!(
        "{} poses registered{kept}; series.csv, series.json, series.png and one folder per pose in {}",
        args.targets.len(),
        args.output.display()
    ));
    Ok(())
}

/// What decides the series' poses besides its targets.
fn made_from(args: &SeriesArgs, options: &RegisterOptions) -> anyhow::Result<MadeFrom> {
    Ok(MadeFrom {
        posereg: env!("CARGO_PKG_VERSION").to_string(),
        source: FileStamp::of(&args.source)?,
        source_labels: FileStamp::of(&args.source_labels)?,
        chained: !args.unchained,
        side: args.side.map(|s| format!("{s:?}").to_lowercase()),
        settings: options_toml(options),
    })
}

/// The last finished pose of `series`, read back from its folder (its field on its target's
/// grid `grids`, its bone motions); a pose whose outputs cannot be read is dropped from the
/// series, to be registered again. None when no pose is finished.
fn resume(
    args: &SeriesArgs,
    series: &mut SeriesFile,
    grids: &[Grid],
    reporter: &Reporter,
) -> Option<Finished> {
    while let Some(last) = series.poses.last() {
        let index = last.pose - 1;
        match Finished::read(&args.folder(index), &grids[index]) {
            Ok(reached) => {
                reporter.say(&format!(
                    "resuming after pose {}: the poses up to it were finished by an earlier run \
                     from the same inputs and settings and are kept",
                    last.pose
                ));
                return Some(reached);
            }
            Err(e) => {
                reporter.warn(&format!(
                    "pose {} is registered again: its outputs cannot be read back ({e})",
                    last.pose
                ));
                series.poses.pop();
            }
        }
    }
    None
}

/// Reads and checks every pose's inputs and the settings against them before any work: a
/// damaged last target stops the series before its first pose is registered or written.
/// Returns each target's grid.
fn check_every_pose(args: &SeriesArgs, options: &RegisterOptions) -> anyhow::Result<Vec<Grid>> {
    let mut grids = Vec::new();
    for index in 0..args.targets.len() {
        let pose = args.pose(index);
        let pair = load_pair(pose.pair.paths(), &options.init.chain)?;
        check_settings(options, &pair, pose.pair.paths())?;
        grids.push(pair.target.grid);
    }
    Ok(grids)
}
