//! One labelled scan and the same knee in several poses, in pose order (`posereg series`).
//! Each pose is registered as `register` would, into OUT/pose_01, OUT/pose_02, …; from the
//! second on, it is reached through the pose before it (pipeline::series: the bones registered
//! from the source with the previous pose's motions tried first, their step from the previous
//! pose blended there and composed with its field), or, unchained, registered from the source
//! with the previous pose's bone motions tried first. OUT/series.csv tabulates every pose's
//! kinematics; OUT/series.json records each pose as it is finished, so a series stopped part
//! way (killed, a pose's target added) resumes where it stopped when run again.

use super::register::{register_files, PairFiles, RegisterFiles, StartOf};
use crate::device::DeviceWanted;
use crate::error::Result;
use crate::io::config::options_toml;
use crate::joints::anatomy::Side;
use crate::pipeline::inputs::{check_settings, load_pair};
use crate::pipeline::register::RegisterOptions;
use crate::pipeline::series::{chain_step, Finished};
use crate::progress::Progress;
use crate::report::quicklook::chart::save_chart;
use crate::report::series::{FileStamp, MadeFrom, PoseRecord, SeriesFile};
use crate::volume::Grid;
use std::path::PathBuf;

/// A series' files and how its poses are reached.
#[derive(Clone, Debug)]
pub struct SeriesFiles {
    /// The source (moving) image: the scan with bone labels.
    pub source: PathBuf,
    /// Its bone labels, on its grid.
    pub labels: PathBuf,
    /// The other poses (fixed images), in pose order.
    pub targets: Vec<PathBuf>,
    /// The output folder: one folder per pose, series.csv, series.json, series.png.
    pub output: PathBuf,
    /// Which knee, when the caller knows (else told from the labels' fibula).
    pub side: Option<Side>,
    /// Reach each pose through the one before (else register each from the source with the
    /// previous pose's bone motions tried first).
    pub chained: bool,
}

impl SeriesFiles {
    /// The output folder of pose `index` (from 0).
    fn folder(&self, index: usize) -> PathBuf {
        self.output.join(format!("pose_{:02}", index + 1))
    }

    /// The registration of pose `index` (from 0).
    fn pose(&self, index: usize) -> RegisterFiles {
        RegisterFiles {
            pair: PairFiles {
                source: self.source.clone(),
                labels: self.labels.clone(),
                target: self.targets[index].clone(),
                output: self.folder(index),
                side: self.side,
            },
            target_mask: None,
            init: None,
        }
    }
}

/// Registers every pose not yet finished in order (resuming after the last one an earlier run
/// on the folder finished from the same inputs and settings) and writes series.csv.
pub fn register_series(
    files: &SeriesFiles,
    options: &RegisterOptions,
    device: &DeviceWanted,
    progress: &dyn Progress,
) -> Result<()> {
    let grids = check_every_pose(files, options)?;
    let _folder = crate::io::prepare_output_folder(&files.output)?;
    let targets = (files.targets.iter())
        .map(|t| FileStamp::of(t))
        .collect::<Result<Vec<_>>>()?;
    let mut series = SeriesFile::finished(&files.output, made_from(files, options)?, &targets);
    let mut previous = resume(files, &mut series, &grids, progress);
    let mut opened = None;
    let finished = series.poses.len();
    for (index, target) in targets.iter().enumerate().skip(finished) {
        let pose = files.pose(index);
        let count = files.targets.len();
        let target_path = pose.pair.target.display();
        progress.say(&format!("pose {} of {count}: {target_path}", index + 1));
        let chained: StartOf = &|opened, pair| {
            let Some(p) = previous.as_ref().filter(|_| files.chained) else {
                return Ok(None);
            };
            let source = (&pair.source, &pair.labels);
            Ok(Some(crate::on_backend!(opened, backend => chain_step(
                backend, source, p.reached(), &pair.target, &options.init, progress,
            ))?))
        };
        let seeds = previous.as_ref().map(|p| &p.motions);
        let starts = (seeds, chained);
        let done = register_files(&pose, options, (device, &mut opened), starts, progress)?;
        let kinematics = done.registered.kinematics.as_ref();
        let pose_of = (index + 1, target.clone());
        (series.poses).push(PoseRecord::new(pose_of, done.summary, kinematics)?);
        series.save(&files.output)?;
        previous = Some(Finished {
            field: done.registered.result.field,
            motions: done.transforms,
        });
    }
    write_summary(files, &series, finished, progress)
}

/// Writes series.csv and series.png from `series`' records and says what the run did
/// (`kept`: the poses an earlier run had finished).
fn write_summary(
    files: &SeriesFiles,
    series: &SeriesFile,
    kept: usize,
    progress: &dyn Progress,
) -> Result<()> {
    crate::io::write_bytes(&files.output.join("series.csv"), series.table())?;
    save_chart(&files.output.join("series.png"), &series.chart())?;
    let beyond = files.folder(files.targets.len());
    if beyond.exists() {
        progress.warn(&format!(
            "{} and any later pose folder are from an earlier, longer series: they are not part \
             of this one (series.csv and series.json list its {} poses); delete them if unwanted",
            beyond.display(),
            files.targets.len()
        ));
    }
    let kept = match kept {
        0 => String::new(),
        n => format!(" ({n} kept from an earlier run)"),
    };
    progress.result(&format!(
        "{} poses registered{kept}; series.csv, series.json, series.png and one folder per pose in {}",
        files.targets.len(),
        files.output.display()
    ));
    Ok(())
}

/// What decides the series' poses besides its targets.
fn made_from(files: &SeriesFiles, options: &RegisterOptions) -> Result<MadeFrom> {
    Ok(MadeFrom {
        posereg: env!("CARGO_PKG_VERSION").to_string(),
        source: FileStamp::of(&files.source)?,
        source_labels: FileStamp::of(&files.labels)?,
        chained: files.chained,
        side: files.side.map(|s| format!("{s:?}").to_lowercase()),
        settings: options_toml(options),
    })
}

/// The last finished pose of `series`, read back from its folder (its field on its target's
/// grid `grids`, its bone motions); a pose whose outputs cannot be read is dropped from the
/// series, to be registered again. None when no pose is finished.
fn resume(
    files: &SeriesFiles,
    series: &mut SeriesFile,
    grids: &[Grid],
    progress: &dyn Progress,
) -> Option<Finished> {
    while let Some(last) = series.poses.last() {
        let index = last.pose - 1;
        match Finished::read(&files.folder(index), &grids[index]) {
            Ok(reached) => {
                progress.say(&format!(
                    "resuming after pose {}: the poses up to it were finished by an earlier run \
                     from the same inputs and settings and are kept",
                    last.pose
                ));
                return Some(reached);
            }
            Err(e) => {
                progress.warn(&format!(
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
fn check_every_pose(files: &SeriesFiles, options: &RegisterOptions) -> Result<Vec<Grid>> {
    let mut grids = Vec::new();
    for index in 0..files.targets.len() {
        let pose = files.pose(index);
        let pair = load_pair(pose.pair.paths(), &options.init.chain)?;
        check_settings(options, &pair, pose.pair.paths())?;
        grids.push(pair.target.grid);
    }
    Ok(grids)
}
