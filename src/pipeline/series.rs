//! Poses reached through their neighbours (`posereg series`). Registering a straight scan
//! straight to 120° of flexion leaves the soft tissue far off: the blend of the bone motions
//! moves tissue the way the straight pose's distances say, which at large angles is not where
//! it went. A pose is instead reached through the one before it. Its bones are registered
//! from the source (their errors do not add up along the series), the previous pose's motions
//! tried first; the source's labels are carried onto the previous pose by its registered
//! field, and the step between the two poses' bone motions is blended there (the blend of a
//! step of a few tens of degrees, from where the tissue already is); the step's field is
//! composed with the previous pose's. Inside each bone the composition is exactly the bone's
//! motion. The registration from the source then starts from it (`Start::Chained`) and
//! refines it as it refines any initial field, so each pose's outputs are the source's.

use crate::abi::Interpolation;
use crate::backend::{resample_volume, Backend, DeviceImage};
use crate::error::{Error, Result};
use crate::images::compose::compose;
use crate::init::articulated::{blend_motions, bone_motions, Chained, InitOptions};
use crate::init::reach::Judge;
use crate::io::field::load_field;
use crate::io::transform::{BoneTransform, BoneTransforms};
use crate::progress::Progress;
use crate::volume::{Field, Grid, Image, Labels, Volume};
use std::path::Path;

/// A finished pose, owned: what the next pose is reached from, whether it was registered in
/// this run or read back from an earlier run's folder.
pub struct Finished {
    /// Its registered field: its point → source point (RAS mm), on its target's grid.
    pub field: Field,
    /// Its bone motions, source → it.
    pub motions: BoneTransforms,
}

impl Finished {
    /// A finished pose read back from its output `folder` (field.nii.gz, transform.json), its
    /// field put on `grid`, its target's, as the target's header gives it (the field's float32
    /// header rounds the affine).
    pub fn read(folder: &Path, grid: &Grid) -> Result<Self> {
        let path = folder.join("field.nii.gz");
        let mut field = load_field(&path)?;
        if !field.grid.same_as(grid, 1e-3) {
            return Err(Error::bad_file(&path, "is not on its target's grid"));
        }
        field.grid = grid.clone();
        let motions = BoneTransforms::load(&folder.join("transform.json"))?;
        Ok(Finished { field, motions })
    }

    /// It as the pose before the next.
    pub fn reached(&self) -> Reached<'_> {
        Reached {
            field: &self.field,
            motions: &self.motions,
        }
    }
}

/// The pose before the one to reach, as its registration left it.
#[derive(Clone, Copy)]
pub struct Reached<'a> {
    /// Its registered field: its point → source point (RAS mm), on its grid.
    pub field: &'a Field,
    /// Its bone motions, source → it.
    pub motions: &'a BoneTransforms,
}

/// Reaches `target` from `previous`: the bones registered from the `source` (with its
/// `labels`), their step from the previous pose blended on the labels carried there, composed
/// with the previous pose's field.
pub fn chain_step<B: Backend>(
    backend: &B,
    (source, labels): (&Volume, &Labels),
    previous: Reached,
    target: &Volume,
    options: &InitOptions,
    progress: &dyn Progress,
) -> Result<Chained> {
    let pair = (source, labels, target);
    let (motions, reports) =
        bone_motions(backend, pair, options, Some(previous.motions), progress)?;
    let step = step_between(previous.motions, &motions)?;
    let carried = carry_labels(backend, labels, previous.field)?;
    let before =
        DeviceImage::upload_field(backend, "previous pose's field", previous.field.clone())?;
    let source = DeviceImage::upload(backend, "source", source.clone())?;
    let judge = Judge::new(
        &source,
        &DeviceImage::upload(backend, "target", target.clone())?,
    );
    let to_source = |step: DeviceImage<B>| compose(backend, &step, &before);
    let blended = blend_motions(
        backend,
        &carried,
        &step,
        options,
        &target.grid,
        (&judge, &to_source),
    )?;
    Ok(Chained {
        motions,
        field: compose(backend, &blended, &before)?.download_field(backend)?,
        reports,
    })
}

/// The source's label map carried onto `field`'s grid (nearest neighbour).
fn carry_labels<B: Backend>(backend: &B, labels: &Labels, field: &Field) -> Result<Labels> {
    let codes: Vec<f32> = labels.data.iter().map(|&c| c as f32).collect();
    let codes = Image::from_data(labels.grid.clone(), codes)?;
    let moved = resample_volume(backend, &codes, field, 0.0, Interpolation::Nearest)?;
    Image::from_data(moved.grid, moved.data.iter().map(|&c| c as u16).collect())
}

/// Each bone's motion from the previous pose to this one: this pose's after the inverse of the
/// previous pose's.
fn step_between(previous: &BoneTransforms, next: &BoneTransforms) -> Result<BoneTransforms> {
    let bones = next.bones.iter().map(|b| {
        let before = previous.bones.iter().find(|p| p.label == b.label);
        let before = before.map(|p| p.affine()).and_then(|m| m.try_inverse());
        let before = before.ok_or_else(|| {
            Error::InvalidInput(format!(
                "the previous pose has no motion for bone {}",
                b.label
            ))
        })?;
        Ok(BoneTransform::new(b.label, &b.name, &(b.affine() * before)))
    });
    Ok(BoneTransforms::new(bones.collect::<Result<_>>()?))
}
