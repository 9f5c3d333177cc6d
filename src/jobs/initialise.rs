//! The articulated initialisation alone (`posereg init`): per-bone rigid, skinning weights,
//! volume skeletal deformation, written as init.json, the bones' .tfm files, init_field.nii.gz
//! and initialised.nii.gz, with the fit told.

use super::outputs::write_kinematics;
use super::register::PairFiles;
use crate::abi::Interpolation;
use crate::backend::resample_volume;
use crate::device::{open_backend, DeviceWanted, Opened};
use crate::error::Result;
use crate::images::metric::correlation;
use crate::init::articulated::{
    initialise_volumes, rigid_field, InitOptions, InitialVolumes, Initialisation, Start,
};
use crate::io::field::save_field;
use crate::io::itk_transform::save_bone_tfms;
use crate::io::nifti::{save_volume, DataType};
use crate::joints::anatomy::Side;
use crate::joints::chain::{self, Link};
use crate::joints::joint::rotation_degrees;
use crate::joints::kinematics::KneeKinematics;
use crate::pipeline::inputs::{check_bones, load_given_motions, Pair};
use crate::pipeline::register::unregistered;
use crate::progress::Progress;
use crate::volume::Volume;
use std::path::Path;

/// The knee's kinematics for the initialisation's bone motions (see crate::joints::kinematics),
/// each joint with its bones' confidence, or None with the reason warned.
fn kinematics(
    side: Option<Side>,
    labels: &crate::Labels,
    chain: &[Link],
    init: &crate::init::articulated::Initialisation,
    progress: &dyn Progress,
) -> Result<Option<KneeKinematics>> {
    let (kinematics, warnings) = init.kinematics(labels, chain, side)?;
    warnings.iter().for_each(|w| progress.warn(w));
    Ok(kinematics)
}

/// Runs the initialisation of the pair `files` names with `options` (from the bone motions in
/// `given` when there are some, else registering the bones) and writes init.json, the bones'
/// .tfm files, init_field.nii.gz, initialised.nii.gz and the kinematics into its folder.
pub fn initialise_files(
    files: &PairFiles,
    options: &InitOptions,
    given: Option<&Path>,
    device: &DeviceWanted,
    progress: &dyn Progress,
) -> Result<()> {
    let (_folder, pair) = files.load(&options.chain, progress)?;
    check_bones(options, &pair.labels, files.paths())?;
    let given = match given {
        Some(path) => Some(load_given_motions(path, &pair.labels, options)?),
        None => None,
    };
    let (opened, line) = open_backend(device)?;
    progress.say(&line);
    let started = std::time::Instant::now();
    let (init, images) = crate::on_backend!(opened, backend => initialise_volumes(
        backend,
        &pair.source,
        &pair.labels,
        &pair.target,
        options,
        given.as_ref().map(Start::Given),
        progress,
    ))?;
    let seconds = started.elapsed().as_secs_f64();
    let folder = &files.output;
    write_initialisation(folder, options, (&init, &images))?;
    if let Some(k) = kinematics(files.side, &pair.labels, &options.chain, &init, progress)? {
        write_kinematics(folder, &k, progress)?;
    }
    progress.result(&format!("initialisation in {seconds:.1} s"));
    say_bones(&init, options, progress);
    say_fit(&opened, &pair, options, (&init, &images), progress)?;
    progress.result(&format!("written to {}", folder.display()));
    progress.save_log(&folder.join("posereg.log"))?;
    Ok(())
}

/// Writes init.json (the bone motions with the skinning, the flexion axis and each bone's
/// report), the bones' .tfm files, init_field.nii.gz and initialised.nii.gz into `folder`.
fn write_initialisation(
    folder: &Path,
    options: &InitOptions,
    (init, images): (&Initialisation, &InitialVolumes),
) -> Result<()> {
    let mut transforms = init.transforms(options);
    transforms.extra.insert(
        "skinning".into(),
        serde_json::json!({
            "method": "shepard inverse-distance",
            "power": crate::init::skinning::SHEPARD_POWER,
            "reach": init.reach,
            "grid_dims": init.weight_grid.dims,
        }),
    );
    transforms.extra.insert(
        "flexion_axis".into(),
        serde_json::json!({
            "point": init.axis.point.as_slice(),
            "direction": init.axis.direction.as_slice(),
        }),
    );
    let reports = serde_json::to_value(&init.reports)
        .map_err(|e| crate::error::Error::InvalidInput(format!("the bones' reports: {e}")))?;
    transforms.extra.insert("bones_report".into(), reports);
    transforms.save(&folder.join("init.json"))?;
    save_bone_tfms(folder, &transforms)?;
    save_field(&folder.join("init_field.nii.gz"), &images.field)?;
    let initialised = folder.join("initialised.nii.gz");
    save_volume(&initialised, &images.initialised, DataType::F32)?;
    Ok(())
}

/// Prints each bone's search, fit and confidence, and its rotation.
fn say_bones(init: &Initialisation, options: &InitOptions, progress: &dyn Progress) {
    for r in &init.reports {
        let last = r.levels.last();
        progress.result(&format!(
            "  {:<8} search {:>6}  mean sq. residual {:.1} -> {:.1}; {}",
            r.name,
            r.search_degrees
                .map(|d| format!("{d:.0}°"))
                .unwrap_or("-".into()),
            r.levels.first().map(|l| l.cost_before).unwrap_or(f64::NAN),
            last.map(|l| l.cost_after).unwrap_or(f64::NAN),
            r.confidence.reason
        ));
        for warning in &r.confidence.warnings {
            progress.warn(warning);
        }
    }
    for (code, m) in &init.motions {
        progress.result(&format!(
            "  {:<8} rotation {:.2}°",
            options.name_of(*code),
            rotation_degrees(m)
        ));
    }
}

/// Prints the blend's inversion residual, the reach, the folds and the correlation with the
/// target of the source as it lies, moved by the root bone only, and initialised.
fn say_fit(
    opened: &Opened,
    pair: &Pair,
    options: &InitOptions,
    (init, images): (&Initialisation, &InitialVolumes),
    progress: &dyn Progress,
) -> Result<()> {
    let (source, target) = (&pair.source, &pair.target);
    let residual = &images.residual.data;
    let worst = residual.iter().cloned().fold(0.0f32, f32::max);
    progress.result(&format!("  blend inversion residual: worst {worst:.3} mm"));
    progress.result(&format!("  {}", reach_line(&init.reach)));
    let repair = &init.repair;
    progress.result(&format!(
        "  folds (det J <= 0.05): {} in the blend, {} after {} smoothing rounds and {} unfolding steps",
        repair.folded_before, repair.folded_after, repair.rounds, repair.unfold_steps
    ));
    let body = |n: usize| target.data[n] > 0.0;
    let fit = |moved: &Volume| correlation(&moved.data, &target.data, body);
    let as_it_lies =
        crate::on_backend!(opened, backend => unregistered(backend, source, &target.grid))?;
    progress.result(&format!(
        "  correlation with target: identity {:.4}",
        fit(&as_it_lies)
    ));
    let root = (init.motions.iter())
        .find(|m| chain::parent_among(&options.chain, m.0, &init.bones).is_none())
        .map(|m| m.1);
    if let Some(root) = root {
        let root_only = crate::on_backend!(opened, backend => resample_volume(
            backend,
            source,
            &rigid_field(&root, &target.grid)?,
            0.0,
            Interpolation::Linear,
        ))?;
        progress.result(&format!(
            "                             root bone only {:.4}",
            fit(&root_only)
        ));
    }
    progress.result(&format!(
        "                             initialised {:.4}",
        fit(&images.initialised)
    ));
    Ok(())
}

/// How far small segments reach and, when several limits were tried, each one's fit.
fn reach_line(reach: &crate::init::reach::ReachChoice) -> String {
    let tried: Vec<String> = reach
        .tried
        .iter()
        .map(|t| format!("{} → {:.4}", t.limit, t.local_correlation))
        .collect();
    match tried.is_empty() {
        true => format!("reach limit {} (given)", reach.limit),
        false => format!(
            "reach limit {:.3} (local correlation with the target: {})",
            reach.limit,
            tried.join(", ")
        ),
    }
}
