//! What `register` and `demo` write into their output folder, the same for both: the warped
//! source, the field and its inverse, the Jacobian, the bone transforms (JSON and ITK .tfm),
//! the figure, report.json and the log.

use super::init::write_kinematics;
use super::progress::Reporter;
use posereg::anatomy::Frame;
use posereg::device::Opened;
use posereg::io::field::save_field;
use posereg::io::itk_transform::save_bone_tfms;
use posereg::io::nifti::{save_volume, DataType};
use posereg::kinematics::KneeKinematics;
use posereg::metric::correlation;
use posereg::quicklook::Figure;
use posereg::register::{unregistered, RegisterOptions, Registration};
use posereg::result_checks::{result_checks, Check, Correlations};
use posereg::{Error, Labels, Volume};
use std::path::Path;

/// The version of report.json's layout: raised when a key changes meaning or goes away
/// (docs/outputs.md describes it).
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

/// Writes every output of `run` into `folder`; returns the correlations and the checks.
pub fn write_registration(
    folder: &Path,
    opened: &Opened,
    run: &Run,
    reporter: &Reporter,
) -> anyhow::Result<(Correlations, Vec<Check>)> {
    let Run {
        source,
        target,
        result,
        options,
        ..
    } = *run;
    let out = |name: &str| folder.join(name);
    save_volume(&out("warped.nii.gz"), &result.warped, DataType::F32)?;
    save_field(&out("field.nii.gz"), &result.field)?;
    save_field(&out("inverse_field.nii.gz"), &result.inverse)?;
    save_volume(&out("jacobian.nii.gz"), &result.jacobian, DataType::F32)?;
    let transform = result.transforms(options);
    transform.save(&out("transform.json"))?;
    save_bone_tfms(folder, &transform)?;
    let before =
        posereg::on_backend!(opened, backend => unregistered(backend, source, &target.grid))?;
    let body = |n: usize| target.data[n] > 0.0;
    let correlations = Correlations {
        before: correlation(&before.data, &target.data, body),
        after: correlation(&result.warped.data, &target.data, body),
    };
    let checks = result_checks(result, correlations, options);
    let centre = match &result.init {
        Some(init) => [init.axis.point.x, init.axis.point.y, init.axis.point.z],
        None => target
            .grid
            .voxel_to_world(target.grid.dims.map(|d| (d as f64 - 1.0) / 2.0)),
    };
    let bones: Vec<(u16, String)> = posereg::chain::present(&options.init.chain, run.labels)
        .into_iter()
        .map(|code| (code, options.init.name_of(code)))
        .collect();
    let frames: Vec<Frame> = run
        .kinematics
        .iter()
        .flat_map(|k| k.frames.iter().map(|f| f.target))
        .collect();
    let figure = Figure {
        target,
        before: &before,
        warped: &result.warped,
        jacobian: &result.jacobian,
        field: &result.field,
        source_grid: &source.grid,
        labels: run.labels,
        bones: &bones,
        points: &result.adaptive.points,
        centre,
        frames: &frames,
        correlations,
    };
    posereg::quicklook::save(&out("quicklook.png"), &figure)?;
    let report = report(opened, run, correlations, &checks);
    let text = serde_json::to_string_pretty(&report)? + "\n";
    posereg::io::write_atomically(&out("report.json"), |tmp| {
        std::fs::write(tmp, text).map_err(|e| Error::io(tmp, e))
    })?;
    if let Some(k) = &run.kinematics {
        write_kinematics(folder, k, reporter)?;
    }
    for check in checks.iter().filter(|c| !c.passed) {
        reporter.warn(&format!("check {} failed: {}", check.name, check.detail));
    }
    Ok((correlations, checks))
}

/// report.json's content.
fn report(
    opened: &Opened,
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
        "device": opened.describe(),
        "seconds": run.seconds,
        "inputs": run.inputs,
        "options": run.options,
        "initialisation": result.init.as_ref().map(|i| serde_json::json!({
            "bones": i.reports,
            "fold_repair": i.repair,
        })),
        "adaptive_stages": result.adaptive.stages,
        "control_points": result.adaptive.points.len(),
        "correlation": {
            "before": correlations.before,
            "after": correlations.after,
            "over": "the target's voxels above 0 (its body), source resampled without and with the field",
        },
        "jacobian": { "min": result.min_jacobian, "folded_share": result.folded_share, "unfolding": result.unfolding },
        "inverse_round_trip": result.round_trip,
        "device_traffic": { "stages": result.traffic, "evaluations": result.adaptive.evaluations },
        "checks": checks,
        "warnings": run.warnings,
    })
}
