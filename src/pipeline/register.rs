//! The whole pipeline, generic over the backend, ordering the stages: the articulated
//! initialisation (optional), the adaptive cubic-RBF stage, the finish's composed field, the
//! dense refinement (optional), the finish's unfolding and outputs. It times each and counts
//! the bytes each moves; the kernels are the stages' to dispatch.

use crate::abi::Interpolation;
use crate::backend::{resample_onto, Backend, DeviceImage, Traffic};
use crate::error::Result;
use crate::finish::{composed, outputs, unfolded};
use crate::images::coverage::mask_and_coverage;
use crate::images::fold_repair::{FoldRepair, SourceLabels};
use crate::images::inverse::RoundTrip;
use crate::init::articulated::{initialise, InitialImages, Initialisation, PairImages, Start};
use crate::init::pins::{bone_pins, initial_bones};
use crate::io::transform::BoneTransforms;
use crate::nonrigid::adaptive::{self, Adaptive, Moving};
use crate::nonrigid::dense::{self, DenseInputs, DenseReport};
use crate::progress::Progress;
use crate::volume::{Field, Grid, Labels, Volume};
use nalgebra::Vector3;

pub use crate::pipeline::options::RegisterOptions;

/// What a registration produces.
pub struct Registration {
    /// What the articulated initialisation found, when run.
    pub init: Option<Initialisation>,
    /// The adaptive stage.
    pub adaptive: Adaptive,
    /// What the dense refinement did, when run.
    pub dense: Option<DenseReport>,
    /// Total field: target point → source point (RAS mm).
    pub field: Field,
    /// The source resampled once through it.
    pub warped: Volume,
    /// The field's Jacobian determinant per target voxel.
    pub jacobian: Volume,
    /// The field's inverse on the source's grid: source point → target point (RAS mm).
    pub inverse: Field,
    /// How closely the inverse undoes the field.
    pub round_trip: RoundTrip,
    /// Smallest Jacobian determinant of the field over the target, folded bone contacts aside.
    pub min_jacobian: f32,
    /// Share of target voxels with determinant ≤ 0, bone contacts aside: where the map folds.
    pub folded_share: f64,
    /// Share of target voxels with determinant ≤ 0 at a bone contact (a voxel whose difference
    /// stencil spans two bones sliding on each other: the determinant measures the slide, not a
    /// fold).
    pub contact_share: f64,
    /// Factor the RBF warp was scaled by to keep the field from folding (1 when untouched).
    pub warp_scale: f64,
    /// The unfolding of the total field where the warp, composed with the initial field, folds
    /// it (all zero when nothing folded).
    pub unfolding: FoldRepair,
    /// Wall time of each stage.
    pub timings: StageTimes,
    /// Host↔device traffic of each stage.
    pub traffic: StageTraffic,
}

/// Bytes moved and work launched by each stage of a registration (zero on the CPU backend).
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StageTraffic {
    /// Articulated initialisation, with the upload of the pair.
    pub initialisation: Traffic,
    /// Adaptive RBF stage.
    pub adaptive: Traffic,
    /// The adaptive warp scaled until it does not fold and composed with the initial field.
    pub composition: Traffic,
    /// The dense refinement (nothing when it is off).
    pub dense: Traffic,
    /// The unfolding of the whole field where it still folds.
    pub unfolding: Traffic,
    /// The final fold check, resampling, inverse and the download of the outputs.
    pub finish: Traffic,
    /// The stages together.
    pub total: Traffic,
}

/// Seconds spent in each stage of a registration.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StageTimes {
    /// Articulated initialisation (0 when skipped).
    pub initialisation: f64,
    /// Adaptive RBF stage.
    pub adaptive: f64,
    /// The adaptive warp scaled until it does not fold and composed with the initial field.
    pub composition: f64,
    /// The dense refinement (0 when it is off).
    pub dense: f64,
    /// The unfolding of the whole field where it still folds.
    pub unfolding: f64,
    /// The final fold check, resampling and inverse.
    pub finish: f64,
}

impl StageTimes {
    /// The whole registration.
    pub fn total(&self) -> f64 {
        self.initialisation
            + self.adaptive
            + self.composition
            + self.dense
            + self.unfolding
            + self.finish
    }
}

/// `source` seen on `grid` without any displacement: the unregistered source on the target's
/// grid (uploaded, resampled where the backend computes, brought back).
pub fn unregistered<B: Backend>(backend: &B, source: &Volume, grid: &Grid) -> Result<Volume> {
    let image = DeviceImage::upload(backend, "source", source.clone())?;
    resample_onto(backend, &image, grid, Interpolation::Linear)?.download(backend)
}

/// What a registration starts from.
#[derive(Clone, Copy)]
pub struct Inputs<'a> {
    /// The moving scan (straight pose).
    pub source: &'a Volume,
    /// Its bone labels.
    pub labels: &'a Labels,
    /// The fixed scan (bent pose): the result is on its grid.
    pub target: &'a Volume,
    /// Where the bones' registration starts when not from the identity: given motions
    /// (`register --init`), a neighbouring pose's to try first, or a pose reached through its
    /// neighbour (`posereg series`).
    pub start: Option<Start<'a>>,
    /// The target's voxels that count as evidence in the non-rigid stage (non-zero inside),
    /// on its grid; none: all of them.
    pub target_mask: Option<&'a Labels>,
}

impl<'a> Inputs<'a> {
    /// The three scans, the bones registered.
    pub fn new(source: &'a Volume, labels: &'a Labels, target: &'a Volume) -> Self {
        Inputs {
            source,
            labels,
            target,
            start: None,
            target_mask: None,
        }
    }
}

/// Registers the source (with its bone labels) to the target.
pub fn register<B: Backend>(
    backend: &B,
    inputs: Inputs,
    options: &RegisterOptions,
    progress: &dyn Progress,
) -> Result<Registration> {
    register_observed(backend, inputs, options, progress, &mut |_| Ok(()))
}

/// [`register`], handing the initialisation's images (where the backend computes) to
/// `observe` before the adaptive stage: what a caller measures the initial field on.
pub fn register_observed<B: Backend>(
    backend: &B,
    inputs: Inputs,
    options: &RegisterOptions,
    progress: &dyn Progress,
    observe: &mut dyn FnMut(&InitialImages<B>) -> Result<()>,
) -> Result<Registration> {
    let mut laps = Laps::new(backend);
    options.check()?;
    let pair = PairImages::upload(backend, inputs.source, inputs.labels, inputs.target)?;
    let start = initialised(backend, &pair, inputs, options, progress)?;
    observe(&start.images)?;
    let (images, bones) = (&start.images, start.bones());
    laps.lap(); // the initialisation
    let source_grid = &pair.source.grid;
    let (mask, coverage, mask_share) =
        mask_and_coverage(backend, source_grid, &images.field, inputs.target_mask)?;
    let moving = Moving {
        image: &images.initialised,
        coverage: &coverage,
        prealigned: start.init.is_some(),
        mask_share,
    };
    let adaptive = adaptive::register(
        backend,
        &moving,
        &pair.target,
        &start.pins,
        &options.adaptive,
        progress,
    )?;
    laps.lap(); // the adaptive stage
    progress.begin("composition", 1);
    let labels = SourceLabels {
        host: inputs.labels,
        device: &pair.labels,
    };
    let bone_map = start.bone_map.as_ref();
    let held = (bones, bone_map);
    let margin = options.bone_margin_mm;
    let (field, scale) = composed(backend, &pair, images, &adaptive, bone_map, margin)?;
    progress.step(&format!("warp scale {scale}"));
    progress.end();
    laps.lap(); // the composition
    let refinement = (field, &mask);
    let (field, dense) = refined(backend, &pair, refinement, bone_map, options, progress)?;
    laps.lap(); // the dense stage
    let whole = unfolded(backend, (field, scale), &labels, images, held, margin)?;
    laps.lap(); // the unfolding
    progress.begin("resampling and inverse", 1);
    let finished = outputs(backend, &pair, &whole.field, &whole.held)?;
    progress.end();
    laps.lap(); // the finish
    let voxels = inputs.target.grid.len() as f64;
    Ok(Registration {
        init: start.init,
        adaptive,
        dense,
        field: finished.field,
        warped: finished.warped,
        jacobian: finished.jacobian,
        inverse: finished.inverse,
        round_trip: finished.round_trip,
        min_jacobian: finished.folds.min,
        folded_share: finished.folds.folded as f64 / voxels,
        contact_share: finished.folds.contacts as f64 / voxels,
        warp_scale: whole.scale,
        unfolding: whole.unfolding,
        timings: laps.times(),
        traffic: laps.traffic(),
    })
}

/// Wall time and device traffic stage by stage: each lap ends a stage, in StageTimes' order.
struct Laps<'b, B: Backend> {
    backend: &'b B,
    clock: std::time::Instant,
    first: Traffic,
    last: (f64, Traffic),
    laps: Vec<(f64, Traffic)>,
}

impl<'b, B: Backend> Laps<'b, B> {
    fn new(backend: &'b B) -> Self {
        let first = backend.traffic();
        Laps {
            backend,
            clock: std::time::Instant::now(),
            first,
            last: (0.0, first),
            laps: Vec::new(),
        }
    }

    /// Ends a stage: the seconds and the traffic since the last lap (or the start).
    fn lap(&mut self) {
        let now = (self.clock.elapsed().as_secs_f64(), self.backend.traffic());
        self.laps.push((now.0 - self.last.0, now.1 - self.last.1));
        self.last = now;
    }

    /// The stages' seconds.
    fn times(&self) -> StageTimes {
        let [initialisation, adaptive, composition, dense, unfolding, finish] =
            self.stages().map(|l| l.0);
        StageTimes {
            initialisation,
            adaptive,
            composition,
            dense,
            unfolding,
            finish,
        }
    }

    /// The stages' traffic, and the whole run's.
    fn traffic(&self) -> StageTraffic {
        let [initialisation, adaptive, composition, dense, unfolding, finish] =
            self.stages().map(|l| l.1);
        StageTraffic {
            initialisation,
            adaptive,
            composition,
            dense,
            unfolding,
            finish,
            total: self.last.1 - self.first,
        }
    }

    fn stages(&self) -> [(f64, Traffic); 6] {
        self.laps[..].try_into().expect("six stages timed")
    }
}

/// What the non-rigid stages start from: the initialisation (None when skipped), its images,
/// and where its bones lie in the target with the pins on their surfaces.
struct Initialised<B: Backend> {
    init: Option<Initialisation>,
    images: InitialImages<B>,
    /// Read by the pins and, after the adaptive stage, by the warp's holding off the bones.
    bone_map: Option<DeviceImage<B>>,
    pins: Vec<Vector3<f64>>,
}

impl<B: Backend> Initialised<B> {
    /// The bones registered, in the initialisation's order (none without it).
    fn bones(&self) -> &[u16] {
        self.init.as_ref().map_or(&[][..], |i| &i.bones[..])
    }
}

/// Runs the initialisation when `options` ask for it and finds its bones in the target.
fn initialised<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    inputs: Inputs,
    options: &RegisterOptions,
    progress: &dyn Progress,
) -> Result<Initialised<B>> {
    let (init, images) = match options.initialise.then_some(&options.init) {
        Some(init_options) => {
            let start = inputs.start;
            let (found, images) =
                initialise(backend, pair, inputs.labels, init_options, start, progress)?;
            (Some(found), images)
        }
        None => (None, InitialImages::identity(backend, pair)?),
    };
    let bones = init.as_ref().map_or(&[][..], |i| &i.bones[..]);
    let bone_map = match bones {
        [] => None,
        bones => Some(initial_bones(backend, pair, &images, bones)?),
    };
    let pins = match &bone_map {
        Some(map) if options.pins_per_bone > 0 => {
            bone_pins(backend, map, bones.len(), options.pins_per_bone)?
        }
        _ => Vec::new(),
    };
    Ok(Initialised {
        init,
        images,
        bone_map,
        pins,
    })
}

/// `field` refined by the dense stage when `options` ask for it (`mask`: the target's voxels
/// that count; `bones`: where the bones are in the target), and what it did.
fn refined<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    (field, mask): (DeviceImage<B>, &DeviceImage<B>),
    bones: Option<&DeviceImage<B>>,
    options: &RegisterOptions,
    progress: &dyn Progress,
) -> Result<(DeviceImage<B>, Option<DenseReport>)> {
    if !options.dense.enabled {
        return Ok((field, None));
    }
    let inputs = DenseInputs {
        source: &pair.source,
        target: &pair.target,
        field: &field,
        mask,
        bones,
    };
    let (refined, report) = dense::refine(backend, &inputs, &options.dense, progress)?;
    Ok((refined, Some(report)))
}

impl Registration {
    /// The registration in the bone-transform format: bone motions (none without the
    /// initialisation) plus the RBF stage's control points and solved coefficients, and how
    /// the total field is composed. field.nii.gz beside it holds that total field sampled on the
    /// target grid.
    pub fn transforms(&self, options: &RegisterOptions) -> BoneTransforms {
        let mut transform = self
            .init
            .as_ref()
            .map(|i| i.transforms(&options.init))
            .unwrap_or_else(|| BoneTransforms::new(Vec::new()));
        transform.extra.insert(
            "rbf".into(),
            serde_json::json!({
                "basis": "cubic, phi(r) = r^3, world RAS mm, on the target grid",
                "lattice_mm": options.adaptive.lattice_mm,
                "lattice_step": self.adaptive.lattice.1,
                "control_points": self.adaptive.points,
                "coefficients": self.adaptive.coefficients,
                "scale": self.warp_scale,
                "composition": "u(x) = R'(x) + u0(x + R'(x)); u0 = inverted skinning of the bone motions; R' = R scaled by the distance to the nearest bone over bone_margin_mm (at most 1; R' = R when 0)",
                "bone_margin_mm": options.bone_margin_mm,
                "unfolding": self.unfolding,
            }),
        );
        transform
    }
}
