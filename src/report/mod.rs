//! Reporting a registration. This module builds report.json: what a registration did and how
//! well, built here so that every writer (the command line, the Python package) writes the
//! same; docs/outputs.md describes each key. Its parts: the checks a result is held to, the
//! quicklook picture, orthogonal-plane pictures, and the paper's figures against known truth.

pub mod evaluate;
pub mod picture;
pub mod quicklook;
pub mod result_checks;
pub mod series;

use crate::backend::Backend;
use crate::error::Result;
use crate::images::metric::correlation;
use crate::joints::kinematics::KneeKinematics;
use crate::pipeline::register::{unregistered, RegisterOptions, Registration};
use crate::report::result_checks::{result_checks, Check, Correlations};
use crate::volume::{Labels, Volume};

/// The version of report.json's layout: raised when a key changes meaning or goes away.
pub const REPORT_SCHEMA: u32 = 1;

/// A finished registration and what it was run on.
pub struct Run<'a> {
    /// The moving scan.
    pub source: &'a Volume,
    /// Its bone labels.
    pub labels: &'a Labels,
    /// The fixed scan.
    pub target: &'a Volume,
    /// The result.
    pub result: &'a Registration,
    /// The settings it ran with.
    pub options: &'a RegisterOptions,
    /// Where the inputs came from (file names, or the phantom's description).
    pub inputs: serde_json::Value,
    /// Warnings about the inputs.
    pub warnings: &'a [String],
    /// Wall time of the registration (s).
    pub seconds: f64,
    /// The knee's kinematics, when they could be told.
    pub kinematics: Option<KneeKinematics>,
}

/// A run judged: its correlations, its checks, report.json's content, and the source as it
/// lay on the target's grid (the "before" of the figures).
pub struct Report {
    /// Correlation with the target before and after.
    pub correlations: Correlations,
    /// The result checks.
    pub checks: Vec<Check>,
    /// report.json.
    pub json: serde_json::Value,
    /// The source resampled onto the target's grid without a field.
    pub unregistered: Volume,
}

/// Judges `run` on `backend` (described as `device` in the report).
pub fn report<B: Backend>(backend: &B, device: &str, run: &Run) -> Result<Report> {
    let target = run.target;
    let before = unregistered(backend, run.source, &target.grid)?;
    let body = |n: usize| target.data[n] > 0.0;
    let correlations = Correlations {
        before: correlation(&before.data, &target.data, body),
        after: correlation(&run.result.warped.data, &target.data, body),
    };
    let checks = result_checks(run.result, correlations, run.options);
    Ok(Report {
        json: content(device, run, correlations, &checks),
        correlations,
        checks,
        unregistered: before,
    })
}

/// report.json's content.
fn content(
    device: &str,
    run: &Run,
    correlations: Correlations,
    checks: &[Check],
) -> serde_json::Value {
    let result = run.result;
    let finished = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    serde_json::json!({
        "schema": REPORT_SCHEMA,
        "posereg": env!("CARGO_PKG_VERSION"),
        "command_line": std::env::args().collect::<Vec<_>>(),
        "finished_unix_seconds": finished,
        "device": device,
        "seconds": run.seconds,
        "inputs": run.inputs,
        "options": run.options.as_run(),
        "initialisation": result.init.as_ref().map(|i| serde_json::json!({
            "bones": i.reports,
            "fold_repair": i.repair,
            "reach": i.reach,
        })),
        "adaptive_stages": result.adaptive.stages,
        "control_points": result.adaptive.points.len(),
        "dense": result.dense,
        "correlation": {
            "before": correlations.before,
            "after": correlations.after,
            "over": "the target's voxels above 0 (its body), source resampled without and with the field",
        },
        "jacobian": {
            "min": result.min_jacobian,
            "folded_share": result.folded_share,
            "bone_contact_share": result.contact_share,
            "unfolding": result.unfolding,
        },
        "inverse_round_trip": result.round_trip,
        "device_traffic": { "stages": result.traffic, "evaluations": result.adaptive.evaluations },
        "checks": checks,
        "warnings": run.warnings,
    })
}
