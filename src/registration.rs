//! The one registration entry every door calls (`posereg register`, `series` and `demo`, the
//! Python package): a checked pair and its settings in, every result out as values (the
//! registration's images and bone motions, the knee's kinematics, report.json's content), so
//! that what the command line writes and what Python returns come from the same steps, checked
//! the same way. Callers load and write; nothing here touches a file.

use crate::device::Opened;
use crate::error::Result;
use crate::init::articulated::Start;
use crate::joints::anatomy::Side;
use crate::joints::kinematics::KneeKinematics;
use crate::pipeline::inputs::{check_settings, Pair, PairPaths};
use crate::pipeline::register::{register_observed, Inputs, RegisterOptions, Registration};
use crate::progress::Progress;
use crate::report::{report, Report, Run};
use crate::volume::{Field, Labels};
use std::path::Path;

/// What one registration is asked to do.
pub struct Request<'a> {
    /// The inputs, loaded and checked (pipeline::inputs).
    pub pair: &'a Pair,
    /// What to call the inputs in errors: their files, or the arguments that held them.
    pub names: PairPaths<'a>,
    /// The settings.
    pub options: &'a RegisterOptions,
    /// Where the bones' registration starts; None: the identity.
    pub start: Option<Start<'a>>,
    /// The target's voxels that count as evidence in the non-rigid stage; None: all.
    pub target_mask: Option<&'a Labels>,
    /// The knee's side when the caller knows it (else told from the anatomy).
    pub side: Option<Side>,
    /// Where the inputs came from, as report.json's `inputs` says it.
    pub inputs: serde_json::Value,
    /// Bring the initialisation's field back too (`posereg demo` measures it).
    pub keep_initial_field: bool,
}

/// report.json's `inputs` for a pair read from files: where each input came from, the bone
/// motions given (`--init`) and the target mask, if any, and how the bones' registration
/// started. One function for every door, so that their reports agree.
pub fn file_inputs(
    files: PairPaths,
    (given, target_mask): (Option<&Path>, Option<&Path>),
    start: Option<Start>,
) -> serde_json::Value {
    serde_json::json!({
        "source": files.source,
        "source_labels": files.labels,
        "target": files.target,
        "bones": given,
        "target_mask": target_mask,
        "start": Start::describe(start),
    })
}

/// Everything one registration gives back.
pub struct Registered {
    /// The registration itself: field, inverse, warped source, Jacobian, bone motions.
    pub result: Registration,
    /// The knee's kinematics, when they could be told.
    pub kinematics: Option<KneeKinematics>,
    /// Why the kinematics could not be told, or what limits them.
    pub kinematics_warnings: Vec<String>,
    /// The run judged: correlations, result checks, report.json's content.
    pub report: Report,
    /// The initialisation's field when asked for and the initialisation ran.
    pub initial_field: Option<Field>,
    /// Wall time of the registration (s), the report's judging left out.
    pub seconds: f64,
}

impl Registered {
    /// The names of the result checks that failed.
    pub fn failed_checks(&self) -> Vec<&'static str> {
        let failed = self.report.checks.iter().filter(|c| !c.passed);
        failed.map(|c| c.name).collect()
    }
}

/// Checks the settings against the pair, registers it on `opened`'s backend, tells the
/// kinematics and judges the result.
pub fn register_pair(
    opened: &Opened,
    request: Request,
    progress: &dyn Progress,
) -> Result<Registered> {
    let Request { pair, options, .. } = request;
    check_settings(options, pair, request.names)?;
    let inputs = Inputs {
        start: request.start,
        target_mask: request.target_mask,
        ..Inputs::new(&pair.source, &pair.labels, &pair.target)
    };
    let started = std::time::Instant::now();
    let mut initial_field = None;
    let result = crate::on_backend!(opened, backend => register_observed(
        backend,
        inputs,
        options,
        progress,
        &mut |images| {
            if request.keep_initial_field {
                initial_field = Some(images.field.download_field(backend)?);
            }
            Ok(())
        },
    ))?;
    let seconds = started.elapsed().as_secs_f64();
    let (kinematics, kinematics_warnings) = match &result.init {
        Some(init) => init.kinematics(&pair.labels, &options.init.chain, request.side)?,
        None => (None, Vec::new()),
    };
    let run = Run {
        source: &pair.source,
        labels: &pair.labels,
        target: &pair.target,
        result: &result,
        options,
        inputs: request.inputs,
        warnings: &pair.warnings,
        seconds,
        kinematics,
    };
    let device = opened.describe();
    let judged = crate::on_backend!(opened, backend => report(backend, &device, &run))?;
    let kinematics = run.kinematics;
    let initial_field = initial_field.filter(|_| result.init.is_some());
    Ok(Registered {
        result,
        kinematics,
        kinematics_warnings,
        report: judged,
        initial_field,
        seconds,
    })
}
