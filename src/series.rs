//! Poses reached through their neighbours (`posereg series`). Registering a straight scan
//! straight to 120° of flexion leaves the soft tissue far off: the blend of the bone motions
//! moves tissue the way the straight pose's distances say, which at large angles is not where
//! it went. A pose is instead reached through the one before it: the source is seen in the
//! previous pose through that pose's registered field (its warped source, the labels carried
//! the same way), the bones are registered from there to this pose (a step of a few tens of
//! degrees, seeded by the step before) and blended, and the step's field and motions are
//! composed with the previous pose's. Registering from the warped source rather than the
//! previous scan keeps the bones' errors from adding up along the series: a bone in the
//! warped source is the source's bone moved by exactly the previous pose's motion. The
//! registration from the source then starts from that composition (`Start::Chained`) and
//! refines it as it refines any initial field, so each pose's outputs are the source's.

use crate::abi::{ComposeParams, Interpolation};
use crate::articulated::{initialise_volumes, Chained, InitOptions, Start};
use crate::backend::{resample_volume, Backend, DeviceImage};
use crate::chain::{self, Link};
use crate::error::{Error, Result};
use crate::io::transform::{BoneTransform, BoneTransforms};
use crate::progress::Progress;
use crate::volume::{Affine, Field, Image, Labels, Volume};

/// The pose before the one to reach, as its registration left it.
#[derive(Clone, Copy)]
pub struct Reached<'a> {
    /// The source resampled through its field (register's warped.nii.gz).
    pub scan: &'a Volume,
    /// Its registered field: its point → source point (RAS mm), on its grid.
    pub field: &'a Field,
    /// Its bone motions, source → it.
    pub motions: &'a BoneTransforms,
    /// The step's motions that reached it from its own neighbour (none for the first pose).
    pub step: Option<&'a BoneTransforms>,
}

/// How the next pose is reached.
pub struct Step {
    /// Where its registration from the source starts.
    pub chained: Chained,
    /// The bone motions from the previous pose to it: the seeds of the step after.
    pub step: BoneTransforms,
}

/// Reaches `target` from `previous`: the source `labels` carried onto the previous pose, the
/// bones registered from the warped source there to `target` and blended, composed with the
/// previous pose.
pub fn chain_step<B: Backend>(
    backend: &B,
    labels: &Labels,
    previous: Reached,
    target: &Volume,
    options: &InitOptions,
    progress: &dyn Progress,
) -> Result<Step> {
    let carried = carry_labels(backend, labels, previous.field)?;
    let start = previous.step.map(Start::Seeded);
    let (init, images) = initialise_volumes(
        backend,
        previous.scan,
        &carried,
        target,
        options,
        start,
        progress,
    )?;
    let step = init.transforms(options);
    let motions = compose_motions(&step, previous.motions, &options.chain)?;
    Ok(Step {
        chained: Chained {
            motions,
            field: compose_fields(backend, &images.field, previous.field)?,
            reports: init.reports,
        },
        step,
    })
}

/// The source's label map carried onto `field`'s grid (nearest neighbour).
fn carry_labels<B: Backend>(backend: &B, labels: &Labels, field: &Field) -> Result<Labels> {
    let codes: Vec<f32> = labels.data.iter().map(|&c| c as f32).collect();
    let codes = Image::from_data(labels.grid.clone(), codes)?;
    let moved = resample_volume(backend, &codes, field, 0.0, Interpolation::Nearest)?;
    Image::from_data(moved.grid, moved.data.iter().map(|&c| c as u16).collect())
}

/// The field `step` (this pose → the previous one) followed by `previous` (the previous pose
/// → the source): u = step + previous ∘ (id + step), on the step's grid.
pub fn compose_fields<B: Backend>(backend: &B, step: &Field, previous: &Field) -> Result<Field> {
    let params = ComposeParams::new(&step.grid, &previous.grid);
    let r = DeviceImage::upload_field(backend, "step field", step.clone())?;
    let u0 = DeviceImage::upload_field(backend, "previous pose's field", previous.clone())?;
    let total = backend.download_one(&backend.compose(&params, &r.data, &u0.data)?)?;
    Image::from_data(step.grid.clone(), bytemuck::cast_vec(total))
}

/// Each bone's motion source → previous pose, then previous → this pose. A bone the step did
/// not register (its carried label fell outside the previous scan) takes its nearest
/// registered ancestor's step.
fn compose_motions(
    step: &BoneTransforms,
    previous: &BoneTransforms,
    chain: &[Link],
) -> Result<BoneTransforms> {
    let stepped: Vec<u16> = step.bones.iter().map(|b| b.label).collect();
    let step_of = |code: u16| -> Affine {
        let at = match stepped.contains(&code) {
            true => Some(code),
            false => chain::parent_among(chain, code, &stepped),
        };
        at.and_then(|a| step.bones.iter().find(|b| b.label == a))
            .map_or_else(Affine::identity, |b| b.affine())
    };
    if previous.bones.iter().all(|b| !stepped.contains(&b.label)) {
        return Err(Error::InvalidInput(
            "no bone of the source's labels lands in the previous pose's scan".into(),
        ));
    }
    let bones = previous
        .bones
        .iter()
        .map(|b| BoneTransform::new(b.label, &b.name, &(step_of(b.label) * b.affine())))
        .collect();
    Ok(BoneTransforms::new(bones))
}
