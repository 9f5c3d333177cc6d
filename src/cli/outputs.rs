//! What `register` and `demo` write into their output folder, the same for both: the warped
//! source, the field and its inverse, the Jacobian, the bone transforms (JSON and ITK .tfm),
//! the figure, report.json and the log.

use super::init::write_kinematics;
use super::progress::Reporter;
use posereg::device::Opened;
use posereg::io::field::save_field;
use posereg::io::itk_transform::save_bone_tfms;
use posereg::io::nifti::{save_volume, DataType};
use posereg::joints::anatomy::Frame;
use posereg::report::quicklook::Figure;
use posereg::report::result_checks::{Check, Correlations};
use posereg::report::{report, Run};
use posereg::Error;
use std::path::Path;

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
    let device = opened.describe();
    let judged = posereg::on_backend!(opened, backend => report(backend, &device, run))?;
    let (correlations, checks) = (judged.correlations, judged.checks);
    let centre = match &result.init {
        Some(init) => [init.axis.point.x, init.axis.point.y, init.axis.point.z],
        None => target
            .grid
            .voxel_to_world(target.grid.dims.map(|d| (d as f64 - 1.0) / 2.0)),
    };
    let bones: Vec<(u16, String)> =
        posereg::joints::chain::present(&options.init.chain, run.labels)
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
        before: &judged.unregistered,
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
    posereg::report::quicklook::save(&out("quicklook.png"), &figure)?;
    let text = serde_json::to_string_pretty(&judged.json)? + "\n";
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
