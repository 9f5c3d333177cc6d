//! What a registration writes into its output folder, the same for `register`, `series` and
//! `demo`: the warped source, the field and its inverse, the Jacobian, the bone transforms
//! (JSON and ITK .tfm), the figure, report.json and the kinematics.

use crate::error::Result;
use crate::io::field::save_field;
use crate::io::itk_transform::save_bone_tfms;
use crate::io::nifti::{save_volume, DataType};
use crate::joints::anatomy::Frame;
use crate::joints::kinematics::KneeKinematics;
use crate::pipeline::inputs::Pair;
use crate::pipeline::register::RegisterOptions;
use crate::progress::Progress;
use crate::registration::Registered;
use crate::report::quicklook::Figure;
use std::path::Path;

/// Writes every output of `done`, a registration of `pair` with `options`, into `folder`, and
/// warns of each failed check.
pub fn write_registration(
    folder: &Path,
    (pair, options): (&Pair, &RegisterOptions),
    done: &Registered,
    progress: &dyn Progress,
) -> Result<()> {
    let result = &done.result;
    let out = |name: &str| folder.join(name);
    // The volumes are compressed on one core each (miniz): two at a time, half the wait
    // (1 mm knee: 0.5 s of a 9 s run written one after another).
    let (one, other) = rayon::join(
        || -> Result<()> {
            save_field(&out("field.nii.gz"), &result.field)?;
            save_volume(&out("warped.nii.gz"), &result.warped, DataType::F32)
        },
        || -> Result<()> {
            save_field(&out("inverse_field.nii.gz"), &result.inverse)?;
            save_volume(&out("jacobian.nii.gz"), &result.jacobian, DataType::F32)
        },
    );
    one.and(other)?;
    let transform = result.transforms(options);
    transform.save(&out("transform.json"))?;
    save_bone_tfms(folder, &transform)?;
    save_quicklook(&out("quicklook.png"), (pair, options), done)?;
    crate::io::save_json(&out("report.json"), &done.report.json)?;
    done.kinematics_warnings
        .iter()
        .for_each(|w| progress.warn(w));
    if let Some(k) = &done.kinematics {
        write_kinematics(folder, k, progress)?;
    }
    for check in done.report.checks.iter().filter(|c| !c.passed) {
        progress.warn(&format!("check {} failed: {}", check.name, check.detail));
    }
    Ok(())
}

/// Draws the quicklook figure: centred on the knee's axis (the target's centre without the
/// initialisation), with the bones, the control points and the joints' frames.
fn save_quicklook(
    path: &Path,
    (pair, options): (&Pair, &RegisterOptions),
    done: &Registered,
) -> Result<()> {
    let (result, target) = (&done.result, &pair.target);
    let centre = match &result.init {
        Some(init) => [init.axis.point.x, init.axis.point.y, init.axis.point.z],
        None => target
            .grid
            .voxel_to_world(target.grid.dims.map(|d| (d as f64 - 1.0) / 2.0)),
    };
    let present = crate::joints::chain::present(&options.init.chain, &pair.labels);
    let bones: Vec<(u16, String)> = present
        .into_iter()
        .map(|code| (code, options.init.name_of(code)))
        .collect();
    let frames: Vec<Frame> = done
        .kinematics
        .iter()
        .flat_map(|k| k.frames.iter().map(|f| f.target))
        .collect();
    let figure = Figure {
        target,
        before: &done.report.unregistered,
        warped: &result.warped,
        jacobian: &result.jacobian,
        field: &result.field,
        source_grid: &pair.source.grid,
        labels: &pair.labels,
        bones: &bones,
        points: &result.adaptive.points,
        centre,
        frames: &frames,
        correlations: done.report.correlations,
    };
    crate::report::quicklook::save(path, &figure)
}

/// Writes kinematics.json and kinematics.csv into `folder` and prints each joint's change.
pub fn write_kinematics(
    folder: &Path,
    kinematics: &KneeKinematics,
    progress: &dyn Progress,
) -> Result<()> {
    crate::io::kinematics::save_kinematics(folder, kinematics)?;
    for joint in &kinematics.joints {
        let each: Vec<String> = joint
            .quantities
            .iter()
            .map(|q| format!("{} {:+.1} {}", q.name, q.change, q.unit))
            .collect();
        let side = kinematics.side;
        progress.result(&format!(
            "  {} ({side:?} knee): {}",
            joint.joint,
            each.join(", ")
        ));
    }
    Ok(())
}
