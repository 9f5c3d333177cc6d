//! Articulated initialisation (paper §2): per-bone rigid registration coarse to fine, skinning
//! weights, and the inverted volume skeletal deformation, giving the initial field u0.

use crate::abi::{Interpolation, ResampleParams};
use crate::backend::{Backend, DeviceImage};
use crate::error::{Error, Result};
use crate::images::fold_repair::{FoldRepair, SourceLabels};
use crate::init::reach::{self, ReachChoice};
use crate::init::rigid::LevelReport;
use crate::init::skinning;
use crate::init::vsd::{initial_field, InitialField};
use crate::io::transform::{BoneTransform, BoneTransforms};
use crate::joints::anatomy::Side;
use crate::joints::chain::Link;
use crate::joints::confidence::Confidence;
use crate::joints::joint::{flexion_axis, JointAxis, KneeBones};
use crate::joints::kinematics::{knee_kinematics, KneeKinematics};
use crate::progress::Progress;
use crate::volume::{Affine, Field, Grid, Image, Labels, Volume};

mod bones;
mod images;
mod options;

use bones::{given_motions, register_bones};
pub use images::{InitialImages, InitialVolumes, PairImages};
pub use options::{bone_name, InitOptions, MAX_REACH_CANDIDATES};

/// One bone's outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BoneReport {
    /// Label code.
    pub label: u16,
    /// Name.
    pub name: String,
    /// Flexion angle of the best search candidate (degrees), when searched.
    pub search_degrees: Option<f64>,
    /// Refinement per level, coarse to fine.
    pub levels: Vec<LevelReport>,
    /// Which motion the bone kept and how sure that is.
    pub confidence: Confidence,
}

/// What the initialisation found (its images stay where the backend computes:
/// [`InitialImages`]).
pub struct Initialisation {
    /// Bone motions, source → target (RAS), in `bones` order.
    pub motions: Vec<(u16, Affine)>,
    /// The flexion axis found from the labels.
    pub axis: JointAxis,
    /// The bones skinned, in weight order.
    pub bones: Vec<u16>,
    /// The grid the skinning weights live on.
    pub weight_grid: Grid,
    /// Folds of the blend removed from the initial field.
    pub repair: FoldRepair,
    /// How far small segments reach, and why (crate::init::reach).
    pub reach: ReachChoice,
    /// Per-bone reports.
    pub reports: Vec<BoneReport>,
}

impl Initialisation {
    /// The bone motions in the on-disk format, named as `options`' chain names them.
    pub fn transforms(&self, options: &InitOptions) -> BoneTransforms {
        transforms_of(&self.motions, options)
    }

    /// The knee's kinematics of these bone motions (frames from the source's `labels`), each
    /// joint with its bones' registration confidence; None, with the reason among the
    /// warnings, when they cannot be told (no femur or tibia, frames that cannot be measured).
    pub fn kinematics(
        &self,
        labels: &Labels,
        chain: &[Link],
        side: Option<Side>,
    ) -> Result<(Option<KneeKinematics>, Vec<String>)> {
        let (kinematics, warnings) = knee_kinematics(labels, chain, &self.motions, side)?;
        let confidence = |bone: &str| {
            let report = self.reports.iter().find(|r| r.name == bone);
            report.map(|r| r.confidence.clone())
        };
        Ok((kinematics.map(|k| k.with_confidence(confidence)), warnings))
    }
}

/// Where the bones' rigid registration starts from, when not from the identity.
#[derive(Clone, Copy, Debug)]
pub enum Start<'a> {
    /// These motions, kept as they are: the rigid stage is skipped (`--init`).
    Given(&'a BoneTransforms),
    /// These motions as first guesses beside the search's (a neighbouring pose's result): a
    /// root starts from its own, a searched bone scores it among its candidates.
    Seeded(&'a BoneTransforms),
    /// A pose reached through the one before it: motions and initial field given, neither the
    /// rigid stage nor the blend run.
    Chained(&'a Chained),
}

impl Start<'_> {
    /// How the bones' registration started, in words (report.json's `inputs.start`).
    pub fn describe(start: Option<Start>) -> &'static str {
        match start {
            None => "identity: each bone found by its rotation search",
            Some(Start::Given(_)) => "given: the bones' motions as --init gave them",
            Some(Start::Seeded(_)) => "seeded: the previous pose's bone motions tried first",
            Some(Start::Chained(_)) => {
                "chained: bones registered with the previous pose's motions tried first, the \
                 tissue reached through the previous pose's registration"
            }
        }
    }
}

/// A pose reached through its neighbour in a series (`posereg series`): the bone motions, the
/// initial field composed along the series, and the reports of the bones' registration.
#[derive(Clone, Debug)]
pub struct Chained {
    /// Bone motions, source → this pose (RAS).
    pub motions: BoneTransforms,
    /// Initial field on this pose's grid: its point → source point (RAS mm).
    pub field: Field,
    /// The bones' registration from the source (the neighbouring pose's motions tried first).
    pub reports: Vec<BoneReport>,
}

/// Runs the articulated initialisation on `pair` (`labels`: its label map on the host), from
/// the identity or from `start`.
pub fn initialise<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    labels: &Labels,
    options: &InitOptions,
    start: Option<Start>,
    progress: &dyn Progress,
) -> Result<(Initialisation, InitialImages<B>)> {
    let (bones, axis) = bones_and_axis(pair, labels, options)?;
    let rigid_steps = match start {
        Some(Start::Given(_) | Start::Chained(_)) => 0,
        _ => bones.len(),
    };
    progress.begin("initialisation", rigid_steps + 1);
    let registered =
        |seeds| register_bones(backend, pair, (&axis, seeds), &bones, options, progress);
    let (motions, reports) = match start {
        Some(Start::Given(given)) => (given_motions(given, &bones)?, Vec::new()),
        Some(Start::Chained(c)) => (given_motions(&c.motions, &bones)?, c.reports.clone()),
        Some(Start::Seeded(seeds)) => registered(Some(seeds))?,
        None => registered(None)?,
    };
    let target = &pair.target.grid;
    let (initial, reach) = match start {
        Some(Start::Chained(c)) => (chained_field(backend, c, target)?, ReachChoice::default()),
        _ => {
            let matrices: Vec<Affine> = motions.iter().map(|m| m.1).collect();
            let source_labels = SourceLabels {
                host: labels,
                device: &pair.labels,
            };
            let judge = reach::Judge::new(&pair.source, &pair.target);
            let blend = Blend {
                labels: &source_labels,
                bones: &bones,
                matrices: &matrices,
                options,
            };
            blend.field(backend, target, (&judge, &|field| Ok(field)))?
        }
    };
    let resample = ResampleParams::new(&pair.source.grid, target, 0.0, Interpolation::Linear);
    let initialised = DeviceImage {
        data: backend.resample(&resample, &pair.source.data, &initial.field.data)?,
        grid: target.clone(),
    };
    progress.step("skinning weights and volume skeletal deformation");
    progress.end();
    let found = Initialisation {
        motions,
        axis,
        weight_grid: skinning::skinning_grid(&pair.labels.grid),
        bones,
        repair: initial.repair,
        reach,
        reports,
    };
    let images = InitialImages {
        field: initial.field,
        residual: initial.residual,
        initialised,
    };
    Ok((found, images))
}

/// Bone motions to blend across the soft tissue of a label map.
struct Blend<'a, B: Backend> {
    labels: &'a SourceLabels<'a, B>,
    /// The bones, in weight order.
    bones: &'a [u16],
    /// Their motions, in `bones` order.
    matrices: &'a [Affine],
    options: &'a InitOptions,
}

/// Brings a field on the judging grid (its point → the blend's label map) to the source
/// scan, for [`reach::choose`].
pub type ToSource<'a, B> = &'a dyn Fn(DeviceImage<B>) -> Result<DeviceImage<B>>;

impl<B: Backend> Blend<'_, B> {
    /// The blend inverted on `target`, its folds repaired, with the reach limit
    /// [`reach::choose`] keeps from `options.reach` (each candidate's field brought to the
    /// source by `to_source` and scored by `judge`): the initial field where the backend
    /// computes.
    fn field(
        &self,
        backend: &B,
        target: &Grid,
        (judge, to_source): (&reach::Judge<B>, ToSource<B>),
    ) -> Result<(InitialField<B>, ReachChoice)> {
        let distances =
            skinning::distances(backend, self.labels.device, self.bones, Some(self.matrices))?;
        let field_on = |limit: f64, grid: &Grid| {
            let weights = distances.weights(backend, skinning::SHEPARD_POWER, limit)?;
            let blend = self.options.blending;
            initial_field(backend, &weights, self.labels, self.matrices, blend, grid)
        };
        let choice = reach::choose(backend, &self.options.reach, judge, |limit, grid| {
            to_source(field_on(limit, grid)?.field)
        })?;
        Ok((field_on(choice.limit, target)?, choice))
    }
}

/// The blend of given bone `motions` across the soft tissue of a label map (one carried into
/// another pose, not necessarily a scan's own), inverted on `target`, as [`initialise`] blends
/// the motions it found: the field where the backend computes. For the step between two
/// poses of a series; `judge` and `to_source` choose the reach as [`Blend::field`] does.
pub fn blend_motions<B: Backend>(
    backend: &B,
    labels: &Labels,
    motions: &BoneTransforms,
    options: &InitOptions,
    target: &Grid,
    judge: (&reach::Judge<B>, ToSource<B>),
) -> Result<DeviceImage<B>> {
    let bones = options.bones_in(labels);
    if bones.is_empty() {
        return Err(Error::InvalidInput(
            "no bone of the label map lies on its grid: nothing to blend".into(),
        ));
    }
    let matrices: Vec<Affine> = given_motions(motions, &bones)?
        .into_iter()
        .map(|m| m.1)
        .collect();
    let device = DeviceImage::upload_labels(backend, labels)?;
    let source_labels = SourceLabels {
        host: labels,
        device: &device,
    };
    let blend = Blend {
        labels: &source_labels,
        bones: &bones,
        matrices: &matrices,
        options,
    };
    Ok(blend.field(backend, target, judge)?.0.field)
}

/// A chained pose's initial field where the backend computes, with no blend residual and no
/// repair (the blend ran in the poses it was composed from).
fn chained_field<B: Backend>(
    backend: &B,
    chained: &Chained,
    target: &Grid,
) -> Result<InitialField<B>> {
    if !chained.field.grid.same_as(target, 1e-3) {
        return Err(Error::InvalidInput(
            "the chained initial field is not on the target's grid".into(),
        ));
    }
    Ok(InitialField {
        field: DeviceImage::upload_field(backend, "chained initial field", chained.field.clone())?,
        residual: DeviceImage {
            data: backend.zeros("no blend residual", target.len())?,
            grid: target.clone(),
        },
        repair: FoldRepair::default(),
    })
}

/// The bones `options` registers in `labels` (on the source's grid) and the knee's flexion
/// axis, or why the labels cannot be registered.
fn bones_and_axis<B: Backend>(
    pair: &PairImages<B>,
    labels: &Labels,
    options: &InitOptions,
) -> Result<(Vec<u16>, JointAxis)> {
    options.check()?;
    if !labels.grid.same_as(&pair.source.grid, 1e-3) {
        return Err(Error::InvalidInput(
            "the label map is not on the source image's grid".into(),
        ));
    }
    let bones = options.bones_in(labels);
    for b in &bones {
        if !labels.data.contains(b) {
            return Err(Error::InvalidInput(format!(
                "bone label {b} has no voxels in the label map"
            )));
        }
    }
    if bones.is_empty() {
        return Err(Error::InvalidInput(
            "the label map has no bone labels (2 femur, 3 tibia, 4 patella, 5 fibula)".into(),
        ));
    }
    crate::abi::check_bone_count(bones.len())?;
    let axis = flexion_axis(labels, KneeBones::of_chain(&options.chain)?)?;
    Ok((bones, axis))
}

/// The bones' rigid registration alone, without the blend: each bone's motion (source →
/// target) and report, in the order `options` registers them, `seeds` tried first.
pub fn bone_motions<B: Backend>(
    backend: &B,
    (source, labels, target): (&Volume, &Labels, &Volume),
    options: &InitOptions,
    seeds: Option<&BoneTransforms>,
    progress: &dyn Progress,
) -> Result<(BoneTransforms, Vec<BoneReport>)> {
    let pair = PairImages::upload(backend, source, labels, target)?;
    let (bones, axis) = bones_and_axis(&pair, labels, options)?;
    progress.begin("bones", bones.len());
    let (motions, reports) =
        register_bones(backend, &pair, (&axis, seeds), &bones, options, progress)?;
    progress.end();
    Ok((transforms_of(&motions, options), reports))
}

/// Bone motions in the bone-transform format, named as the chain names them.
fn transforms_of(motions: &[(u16, Affine)], options: &InitOptions) -> BoneTransforms {
    BoneTransforms::new(
        motions
            .iter()
            .map(|(code, m)| BoneTransform::new(*code, &options.name_of(*code), m))
            .collect(),
    )
}

/// [`initialise`] from host volumes to host volumes: the pair goes up once, the three images
/// come back once (what `posereg init` writes).
pub fn initialise_volumes<B: Backend>(
    backend: &B,
    source: &Volume,
    labels: &Labels,
    target: &Volume,
    options: &InitOptions,
    start: Option<Start>,
    progress: &dyn Progress,
) -> Result<(Initialisation, InitialVolumes)> {
    let pair = PairImages::upload(backend, source, labels, target)?;
    let (found, images) = initialise(backend, &pair, labels, options, start, progress)?;
    Ok((found, images.download(backend)?))
}

/// A field that moves every point by one rigid motion (source → target), on `grid`: what
/// aligning a single bone gives the whole volume.
pub fn rigid_field(motion: &Affine, grid: &crate::volume::Grid) -> Result<Field> {
    let inverse = motion
        .try_inverse()
        .ok_or_else(|| Error::InvalidInput("motion is singular".into()))?;
    let data = (0..grid.len())
        .map(|n| {
            let w = grid.world_of(n);
            let q = inverse * nalgebra::Vector4::new(w[0], w[1], w[2], 1.0);
            [
                (q.x - w[0]) as f32,
                (q.y - w[1]) as f32,
                (q.z - w[2]) as f32,
            ]
        })
        .collect();
    Image::from_data(grid.clone(), data)
}
