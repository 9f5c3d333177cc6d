//! One pair of files registered and its outputs written: `posereg register`, and each pose of
//! `posereg series`.

use super::outputs::write_registration;
use crate::device::{open_backend, DeviceWanted, Opened};
use crate::error::Result;
use crate::init::articulated::{Chained, Start};
use crate::io::transform::BoneTransforms;
use crate::io::{prepare_output_folder, OutputFolder};
use crate::joints::anatomy::Side;
use crate::joints::chain::Link;
use crate::pipeline::inputs::{load_given_motions, load_pair, load_target_mask, Pair, PairPaths};
use crate::pipeline::register::RegisterOptions;
use crate::progress::Progress;
use crate::registration::{file_inputs, register_pair, Registered, Request};
use std::path::PathBuf;

/// The straight scan with its bone labels, the bent scan, and where outputs go.
#[derive(Clone, Debug)]
pub struct PairFiles {
    /// The source (moving) image: the scan with bone labels.
    pub source: PathBuf,
    /// Its bone labels, on its grid.
    pub labels: PathBuf,
    /// The target (fixed) image: the other pose; outputs are on its grid.
    pub target: PathBuf,
    /// The output folder (created if missing).
    pub output: PathBuf,
    /// Which knee, when the caller knows (else told from the labels' fibula).
    pub side: Option<Side>,
}

impl PairFiles {
    /// Where the three inputs are.
    pub fn paths(&self) -> PairPaths<'_> {
        PairPaths {
            source: &self.source,
            labels: &self.labels,
            target: &self.target,
        }
    }

    /// Prepares the output folder, then loads and checks the inputs (the labels against the
    /// kinematic chain), warning of what their checks found.
    pub fn load(&self, chain: &[Link], progress: &dyn Progress) -> Result<(OutputFolder, Pair)> {
        let folder = prepare_output_folder(&self.output)?;
        let pair = load_pair(self.paths(), chain)?;
        for warning in &pair.warnings {
            progress.warn(warning);
        }
        Ok((folder, pair))
    }
}

/// A registration's files: the pair, and optionally a target mask and the bone motions to
/// start from.
#[derive(Clone, Debug)]
pub struct RegisterFiles {
    /// The scans, the labels and the output folder.
    pub pair: PairFiles,
    /// Only the mask's non-zero voxels count as evidence for the non-rigid stage.
    pub target_mask: Option<PathBuf>,
    /// Bone transforms to start from instead of registering the bones.
    pub init: Option<PathBuf>,
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

/// Where the bones' registration of a loaded pair starts: `series` works it out from the pair
/// and the backend (its previous pose), `register` starts from the identity.
pub type StartOf<'s> = &'s dyn Fn(&Opened, &Pair) -> Result<Option<Chained>>;

/// The backend `opened` holds, opening the one `device` asks for the first time.
fn backend<'o>(
    device: &DeviceWanted,
    opened: &'o mut Option<Opened>,
    progress: &dyn Progress,
) -> Result<&'o Opened> {
    if opened.is_none() {
        let (backend, line) = open_backend(device)?;
        progress.say(&line);
        *opened = Some(backend);
    }
    Ok(opened.as_ref().expect("opened above"))
}

/// Loads the pair `files` names, registers it with `options` on the backend `opened` holds
/// (opening the one `device` asks for the first time), and writes every output into its
/// folder. The bones start from the given motions, else from a chained pose `chained` makes,
/// else from `seeds` tried first, else from the identity. The log so far goes beside them.
pub fn register_files(
    files: &RegisterFiles,
    options: &RegisterOptions,
    (device, opened): (&DeviceWanted, &mut Option<Opened>),
    (seeds, chained): (Option<&BoneTransforms>, StartOf),
    progress: &dyn Progress,
) -> Result<Written> {
    let (_folder, pair) = files.pair.load(&options.init.chain, progress)?;
    let given = match &files.init {
        Some(path) => Some(load_given_motions(path, &pair.labels, &options.init)?),
        None => None,
    };
    let mask = match &files.target_mask {
        Some(path) => Some(load_target_mask(
            path,
            &pair.target.grid,
            &files.pair.target,
        )?),
        None => None,
    };
    let opened = backend(device, opened, progress)?;
    let chained = chained(opened, &pair)?;
    let start = (given.as_ref().map(Start::Given))
        .or(chained.as_ref().map(Start::Chained))
        .or(seeds.map(Start::Seeded));
    let request = Request {
        pair: &pair,
        names: files.pair.paths(),
        options,
        start,
        target_mask: mask.as_ref(),
        side: files.pair.side,
        inputs: file_inputs(
            files.pair.paths(),
            (files.init.as_deref(), files.target_mask.as_deref()),
            start,
        ),
        keep_initial_field: false,
    };
    let registered = register_pair(opened, request, progress)?;
    let folder = &files.pair.output;
    write_registration(folder, (&pair, options), &registered, progress)?;
    let summary = summary(&files.pair, start, &registered);
    progress.result(&format!(
        "registered in {:.1} s: correlation {:.3} -> {:.3}, {} control points, Jacobian min {:.3}; outputs in {}",
        registered.seconds,
        registered.report.correlations.before,
        registered.report.correlations.after,
        registered.result.adaptive.points.len(),
        registered.result.min_jacobian,
        folder.display()
    ));
    progress.save_log(&folder.join("posereg.log"))?;
    Ok(Written {
        transforms: registered.result.transforms(options),
        registered,
        summary,
    })
}

/// report.json's headline figures for a summary over several registrations (series.json).
fn summary(files: &PairFiles, start: Option<Start>, done: &Registered) -> serde_json::Value {
    let correlations = &done.report.correlations;
    serde_json::json!({
        "folder": files.output,
        "target": files.target,
        "start": Start::describe(start),
        "seconds": done.seconds,
        "correlation": { "before": correlations.before, "after": correlations.after },
        "control_points": done.result.adaptive.points.len(),
        "jacobian_min": done.result.min_jacobian,
        "checks_failed": done.failed_checks(),
    })
}
