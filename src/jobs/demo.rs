//! A phantom pair made on the spot and registered (`posereg demo`): the phantom knee straight
//! and bent, the registration's outputs, the inputs and the truth written, and the result
//! told against the truth.

use super::outputs::write_registration;
use crate::device::{open_backend, DeviceWanted};
use crate::error::Result;
use crate::init::articulated::bone_name;
use crate::io::field::save_field;
use crate::io::nifti::{save_labels, save_volume, DataType};
use crate::io::transform::BoneTransforms;
use crate::joints::joint::rotation_degrees;
use crate::labels as label;
use crate::phantom::{generate, Phantom, PhantomSize, PhantomSpec};
use crate::pipeline::inputs::{Pair, PairPaths};
use crate::pipeline::register::RegisterOptions;
use crate::progress::Progress;
use crate::registration::{Registered, Request};
use crate::report::evaluate::field_error;
use crate::volume::{Field, Labels};
use std::path::Path;

/// The phantom pair a demo registers.
#[derive(Clone, Copy, Debug)]
pub struct DemoPair {
    /// The phantom's grid.
    pub size: PhantomSize,
    /// The target's flexion (degrees); the source is straight.
    pub flexion: f64,
}

impl DemoPair {
    /// The phantom straight (seed 1) and bent by `flexion` (seed 2), each with its truth.
    pub fn generate(&self) -> Result<(Phantom, Phantom)> {
        let spec = |flexion_degrees, seed| PhantomSpec {
            size: self.size,
            flexion_degrees,
            seed,
            ..Default::default()
        };
        Ok((generate(&spec(0.0, 1))?, generate(&spec(self.flexion, 2))?))
    }
}

/// Makes the pair, registers it with `options`, writes everything into `folder` and tells the
/// figures against the truth and where the outputs are.
pub fn run_demo(
    demo: DemoPair,
    options: &RegisterOptions,
    folder: &Path,
    device: &DeviceWanted,
    progress: &dyn Progress,
) -> Result<()> {
    let _folder = crate::io::prepare_output_folder(folder)?;
    let (opened, line) = open_backend(device)?;
    progress.say(&line);
    progress.result(&format!(
        "making a {:?} knee phantom straight and bent {}° ...",
        demo.size, demo.flexion
    ));
    let (source, target) = demo.generate()?;
    let truth = (target.truth_field, target.truth, target.labels);
    let pair = Pair {
        source: source.image,
        labels: source.labels,
        target: target.image,
        warnings: Vec::new(),
    };
    progress.result("registering ...");
    let request = Request {
        pair: &pair,
        names: PairPaths {
            source: Path::new("the straight phantom"),
            labels: Path::new("the straight phantom's labels"),
            target: Path::new("the bent phantom"),
        },
        options,
        start: None,
        target_mask: None,
        side: None,
        inputs: serde_json::json!({
            "phantom": format!("{:?}, straight and bent {}°", demo.size, demo.flexion),
            "start": crate::init::articulated::Start::describe(None),
        }),
        keep_initial_field: true,
    };
    let done = crate::registration::register_pair(&opened, request, progress)?;
    let out = |name: &str| folder.join(name);
    save_volume(&out("source.nii.gz"), &pair.source, DataType::F32)?;
    save_labels(&out("source_labels.nii.gz"), &pair.labels)?;
    save_volume(&out("target.nii.gz"), &pair.target, DataType::F32)?;
    save_field(&out("truth_field.nii.gz"), &truth.0)?;
    truth.1.save(&out("truth.json"))?;
    write_registration(folder, (&pair, options), &done, progress)?;
    progress.result(&format!(
        "done in {:.1} s on {}",
        done.seconds,
        opened.describe()
    ));
    say_bone_errors(&done, &truth.1, progress);
    say_field_errors(&pair, &done, (&truth.0, &truth.2), progress)?;
    progress.result(&format!(
        "outputs in {}: what `posereg register` writes (warped.nii.gz, field.nii.gz, \
         inverse_field.nii.gz, jacobian.nii.gz, transform.json, bones/*.tfm, report.json, \
         quicklook.png), the inputs and the truth",
        folder.display()
    ));
    progress.save_log(&folder.join("posereg.log"))?;
    Ok(())
}

/// Prints each bone's motion against the truth.
fn say_bone_errors(done: &Registered, truth: &BoneTransforms, progress: &dyn Progress) {
    let motions = (done.result.init.as_ref())
        .map(|i| i.motions.clone())
        .unwrap_or_default();
    if !motions.is_empty() {
        progress.result("bone motions against the truth:");
    }
    for (code, m) in &motions {
        let truth = truth
            .bones
            .iter()
            .find(|t| t.label == *code)
            .map(|t| t.affine());
        if let Some(truth) = truth {
            let angle = rotation_degrees(&(m.try_inverse().unwrap_or(*m) * truth));
            let shift = (m.fixed_view::<3, 1>(0, 3) - truth.fixed_view::<3, 1>(0, 3)).norm();
            progress.result(&format!(
                "  {:<8} rotation error {angle:.2}°, translation difference {shift:.2} mm",
                bone_name(*code)
            ));
        }
    }
}

/// Prints the field's error against the truth inside the body, where both scans see it (the
/// bent shank brings in anatomy the straight scan never saw), before, after the
/// initialisation and after the registration, and the field's figures.
fn say_field_errors(
    pair: &Pair,
    done: &Registered,
    (truth_field, target_labels): (&Field, &Labels),
    progress: &dyn Progress,
) -> Result<()> {
    let seen = crate::report::evaluate::seen_by_both(truth_field, &pair.source.grid, 0.0);
    let body = |n: usize| target_labels.data[n] != label::OUTSIDE && seen[n];
    let zero = crate::Image::filled(pair.target.grid.clone(), [0.0f32; 3]);
    let before = field_error(&zero, truth_field, body)?;
    let after = field_error(&done.result.field, truth_field, body)?;
    if let Some(initial_field) = &done.initial_field {
        let initial = field_error(initial_field, truth_field, body)?;
        progress.result(&format!(
            "after the articulated initialisation: mean error {:.2} mm, within 2 voxels {:.1}%",
            initial.mean_mm,
            100.0 * initial.within_2_voxels
        ));
    }
    progress.result(&format!(
        "inside the body, where both scans see it ({} voxels):",
        after.voxels
    ));
    progress.result(&format!(
        "  mean error      {:.2} mm -> {:.2} mm   (within 2 voxels {:.1}% -> {:.1}%, within 4 {:.1}% -> {:.1}%)",
        before.mean_mm,
        after.mean_mm,
        100.0 * before.within_2_voxels,
        100.0 * after.within_2_voxels,
        100.0 * before.within_4_voxels,
        100.0 * after.within_4_voxels
    ));
    let correlations = &done.report.correlations;
    progress.result(&format!(
        "  correlation     {:.3} -> {:.3}   (over the target's body)",
        correlations.before, correlations.after
    ));
    let result = &done.result;
    let free = result.adaptive.points.iter().filter(|p| !p.pinned).count();
    progress.result(&format!(
        "  control points  {free} adaptive + {} pinned on bone surfaces; Jacobian min {:.3}, {:.4}% folded",
        result.adaptive.points.len() - free,
        result.min_jacobian,
        100.0 * result.folded_share
    ));
    Ok(())
}
