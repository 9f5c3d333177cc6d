//! The whole pipeline, generic over the backend: articulated initialisation (optional), the
//! adaptive cubic-RBF stage, the composed field, a fold check, and the source resampled once.

use crate::abi::{BoneLookupParams, ComposeParams, FadeParams, Interpolation, ResampleParams};
use crate::backend::{resample_onto, Backend, DeviceImage, Traffic};
use crate::error::{Error, Result};
use crate::images::fold_repair::{
    bones_at_source, determinant, rigid_bones, unfold_registration, FoldRepair, Folds, SourceLabels,
};
use crate::images::inverse::{invert, round_trip, RoundTrip};
use crate::images::regions;
use crate::init::articulated::{initialise, InitialImages, Initialisation, PairImages, Start};
use crate::io::transform::BoneTransforms;
use crate::nonrigid::adaptive::{self, Adaptive, Moving};
use crate::nonrigid::dense::{self, DenseInputs, DenseReport};
use crate::progress::Progress;
use crate::volume::{Field, Grid, Image, Labels, Volume};
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
    /// The dense refinement, with the composition and unfolding of the field it refines.
    pub dense: Traffic,
    /// The final fold check, resampling, inverse and the download of the outputs.
    pub finish: Traffic,
    /// The four together.
    pub total: Traffic,
}

/// Seconds spent in each stage of a registration.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StageTimes {
    /// Articulated initialisation (0 when skipped).
    pub initialisation: f64,
    /// Adaptive RBF stage.
    pub adaptive: f64,
    /// The dense refinement, with the composition and unfolding of the field it refines.
    pub dense: f64,
    /// The final fold check, resampling and inverse.
    pub finish: f64,
}

impl StageTimes {
    /// The whole registration.
    pub fn total(&self) -> f64 {
        self.initialisation + self.adaptive + self.dense + self.finish
    }
}

/// Up to `per_bone` points on the surface in the target of each of `bones` bones: boundary
/// voxels of the region whose source point the initial field puts in that bone (`bone_map`,
/// [`initial_bones`]), spread by farthest-point sampling. The map (one value per voxel) comes
/// back for the boundaries and the sampling.
pub fn bone_pins<B: Backend>(
    backend: &B,
    bone_map: &DeviceImage<B>,
    bones: usize,
    per_bone: usize,
) -> Result<Vec<Vector3<f64>>> {
    let grid = &bone_map.grid;
    let bone_of = backend.download_one(&bone_map.data)?;
    let mut pins = Vec::new();
    for index in 1..=bones {
        let inside: Vec<bool> = bone_of.iter().map(|&b| b == index as f32).collect();
        pins.extend(spread(&surface_points(grid, &inside), per_bone));
    }
    Ok(pins)
}

/// 1 + the position among `bones` of the bone in which the initial field puts each target
/// voxel's source point, 0 for soft tissue: where the initialisation moves a bone rigidly.
pub fn initial_bones<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    initial: &InitialImages<B>,
    bones: &[u16],
) -> Result<DeviceImage<B>> {
    let grid = &initial.field.grid;
    let lookup = BoneLookupParams::new(&pair.labels.grid, grid, bones, f32::MAX)?;
    let data = backend.bone_at_source(
        &lookup,
        &initial.field.data,
        &initial.residual.data,
        &pair.labels.data,
    )?;
    Ok(DeviceImage {
        data,
        grid: grid.clone(),
    })
}

/// The adaptive `warp` held off the `bones` bones: zero where the initial field moves a bone
/// (`bone_map`, [`initial_bones`]), so that
/// the bones of the total field move exactly by their rigid motions, and rising linearly to
/// the whole warp `margin_mm` from the nearest bone, so that the field has no step at a bone's
/// surface. The warp's pins hold it near zero on each bone's surface already, but between
/// them it bends the bone: by 0.3 mm on average at 90° (the knee at 2 mm), as much as the
/// rigid stage's own error.
fn held_off_bones<B: Backend>(
    backend: &B,
    bone_map: &DeviceImage<B>,
    bones: usize,
    margin_mm: f64,
    warp: &DeviceImage<B>,
) -> Result<DeviceImage<B>> {
    let distance = regions::distance_maps(backend, bone_map, bones)?;
    let params = FadeParams::new(&warp.grid, bones, margin_mm);
    Ok(DeviceImage {
        data: backend.fade_warp(&params, &warp.data, &distance)?,
        grid: warp.grid.clone(),
    })
}

/// World positions of the voxels of `inside` with a 6-neighbour outside it.
fn surface_points(grid: &Grid, inside: &[bool]) -> Vec<Vector3<f64>> {
    let d = grid.dims;
    (0..grid.len())
        .filter(|&n| {
            if !inside[n] {
                return false;
            }
            let (i, j, k) = (n % d[0], (n / d[0]) % d[1], n / (d[0] * d[1]));
            let neighbours = [
                (i > 0).then(|| n - 1),
                (i + 1 < d[0]).then(|| n + 1),
                (j > 0).then(|| n - d[0]),
                (j + 1 < d[1]).then(|| n + d[0]),
                (k > 0).then(|| n - d[0] * d[1]),
                (k + 1 < d[2]).then(|| n + d[0] * d[1]),
            ];
            neighbours.iter().any(|m| m.is_some_and(|m| !inside[m]))
        })
        .map(|n| grid.world_of(n))
        .collect()
}

/// Up to `count` of `points`, each farthest from those chosen before it, from the first.
fn spread(points: &[Vector3<f64>], count: usize) -> Vec<Vector3<f64>> {
    let Some(first) = points.first() else {
        return Vec::new();
    };
    let mut chosen = vec![*first];
    let mut nearest: Vec<f64> = points.iter().map(|p| (p - first).norm()).collect();
    while chosen.len() < count {
        let (k, far) = nearest
            .iter()
            .enumerate()
            .fold((0, 0.0), |b, (k, &v)| if v > b.1 { (k, v) } else { b });
        if far < 1e-6 {
            break;
        }
        chosen.push(points[k]);
        for (m, p) in points.iter().enumerate() {
            nearest[m] = nearest[m].min((p - points[k]).norm());
        }
    }
    chosen
}

/// `source` seen on `grid` without any displacement: the unregistered source on the target's
/// grid (uploaded, resampled where the backend computes, brought back).
pub fn unregistered<B: Backend>(backend: &B, source: &Volume, grid: &Grid) -> Result<Volume> {
    let image = DeviceImage::upload(backend, "source", source.clone())?;
    resample_onto(backend, &image, grid, Interpolation::Linear)?.download(backend)
}

/// The initial images when the articulated initialisation is skipped: no displacement, and
/// the source just resampled onto the target's grid.
fn no_initialisation<B: Backend>(backend: &B, pair: &PairImages<B>) -> Result<InitialImages<B>> {
    let grid = &pair.target.grid;
    let zeros = |what, per_voxel| -> Result<DeviceImage<B>> {
        Ok(DeviceImage {
            data: backend.zeros(what, per_voxel * grid.len())?,
            grid: grid.clone(),
        })
    };
    Ok(InitialImages {
        field: zeros("zero displacement", 3)?,
        residual: zeros("zero residual", 1)?,
        initialised: resample_onto(backend, &pair.source, grid, Interpolation::Linear)?,
    })
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
    let (mask, coverage, mask_share) = coverage(backend, &pair, images, inputs.target_mask)?;
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
    let held = (bones, start.bone_map.as_ref());
    let (field, scale) = composed(backend, &pair, images, &adaptive, held, options)?;
    progress.step(&format!("warp scale {scale}"));
    progress.end();
    let bones_held = start.bone_map.as_ref().map(|map| (map, bones.len()));
    let refinement = (field, &mask);
    let (field, dense) = refined(backend, &pair, refinement, bones_held, options, progress)?;
    let whole = unfolded(backend, (field, scale), &labels, images, held, options)?;
    laps.lap(); // the composition, the dense stage and the unfolding
    progress.begin("resampling and inverse", 1);
    let finished = outputs(backend, &pair, &whole.field, &whole.held)?;
    progress.end();
    laps.lap(); // the finish
    let source = inputs.source;
    let voxels = inputs.target.grid.len() as f64;
    Ok(Registration {
        init: start.init,
        adaptive,
        dense,
        field: finished.field,
        warped: finished.warped,
        jacobian: finished.jacobian,
        inverse: finished.inverse,
        round_trip: round_trip(
            &finished.inverse_residual,
            |n| source.data[n] > 0.0,
            "the source's voxels above 0 (its body)",
        ),
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

    /// The four stages' seconds.
    fn times(&self) -> StageTimes {
        let [initialisation, adaptive, dense, finish] = self.stages().map(|l| l.0);
        StageTimes {
            initialisation,
            adaptive,
            dense,
            finish,
        }
    }

    /// The four stages' traffic, and the whole run's.
    fn traffic(&self) -> StageTraffic {
        let [initialisation, adaptive, dense, finish] = self.stages().map(|l| l.1);
        StageTraffic {
            initialisation,
            adaptive,
            dense,
            finish,
            total: self.last.1 - self.first,
        }
    }

    fn stages(&self) -> [(f64, Traffic); 4] {
        self.laps[..].try_into().expect("four stages timed")
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
        None => (None, no_initialisation(backend, pair)?),
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
/// that count; `bones`: where the bones are in the target and how many), and what it did.
fn refined<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    (field, mask): (DeviceImage<B>, &DeviceImage<B>),
    bones: Option<(&DeviceImage<B>, usize)>,
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

/// The target mask (1 where the target's voxels count, 0 elsewhere: all of the target without
/// one) and where the initialised source covers it, where the backend computes; and the
/// mask's share of the target grid.
fn coverage<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    images: &InitialImages<B>,
    target_mask: Option<&Labels>,
) -> Result<(DeviceImage<B>, DeviceImage<B>, f64)> {
    let grid = &pair.target.grid;
    let mask: Vec<f32> = match target_mask {
        Some(mask) => {
            crate::backend::check_grids(&mask.grid, grid)?;
            mask.data.iter().map(|&m| (m > 0) as u8 as f32).collect()
        }
        None => vec![1.0; grid.len()],
    };
    let mask_share = mask.iter().filter(|&&m| m > 0.0).count().max(1) as f64 / mask.len() as f64;
    let mask = DeviceImage {
        data: backend.upload("target mask", mask)?,
        grid: grid.clone(),
    };
    let params = ResampleParams::new(&pair.source.grid, grid, 0.0, Interpolation::Linear);
    let coverage = DeviceImage {
        data: backend.coverage(&params, &images.field.data, &mask.data)?,
        grid: grid.clone(),
    };
    Ok((mask, coverage, mask_share))
}

/// The whole field where the backend computes, the factor its warp was scaled by, and how
/// it was unfolded.
struct TotalField<B: Backend> {
    field: DeviceImage<B>,
    /// The bone numbers of the voxels whose source point lies in a bone (fold statistics' held).
    held: B::Buffer<f32>,
    scale: f64,
    unfolding: FoldRepair,
}

/// The total field of the adaptive warp, held off the bones where the initial field moves them
/// (`bone_map`), and the `initial` field, and the factor the warp was scaled by.
///
/// Step control: the added warp itself must not fold; while it does, it is shrunk. Folds of
/// the initial field (skinning at large angles) are carried into the total field and
/// unfolded there ([`unfolded`]), but are not the warp's to undo. (Counting the total field's
/// folds instead threw away 94% of a good warp at 60° over one voxel sampled differently
/// inside the initial field's fold: 1.34 → 1.77 mm.)
fn composed<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    initial: &InitialImages<B>,
    adaptive: &Adaptive,
    (bones, bone_map): (&[u16], Option<&DeviceImage<B>>),
    options: &RegisterOptions,
) -> Result<(DeviceImage<B>, f64)> {
    let grid = &pair.target.grid;
    let nothing_held = backend.zeros("nothing held", grid.len())?;
    let mut scale = 1.0;
    let warp = loop {
        let warp = adaptive.warp_field(backend, scale)?;
        let (_, folds) = determinant(backend, &warp, &nothing_held)?;
        if folds.folded == 0 || scale < 0.1 {
            break warp;
        }
        scale *= 0.5;
    };
    let warp = match bone_map.filter(|_| options.bone_margin_mm > 0.0) {
        Some(map) => held_off_bones(backend, map, bones.len(), options.bone_margin_mm, &warp)?,
        None => warp,
    };
    let field = DeviceImage {
        data: backend.compose(
            &ComposeParams::new(grid, &initial.field.grid),
            &warp.data,
            &initial.field.data,
        )?,
        grid: grid.clone(),
    };
    Ok((field, scale))
}

/// The whole `field` unfolded where it folds (after the dense refinement, which cannot fold
/// it but keeps the initial field's folds, where it ran).
fn unfolded<B: Backend>(
    backend: &B,
    (field, scale): (DeviceImage<B>, f64),
    labels: &SourceLabels<B>,
    initial: &InitialImages<B>,
    (bones, bone_map): (&[u16], Option<&DeviceImage<B>>),
    options: &RegisterOptions,
) -> Result<TotalField<B>> {
    let held = bones_at_source(backend, &field, labels, bones)?;
    let (det, folds) = determinant(backend, &field, &held)?;
    // Only a field that folds is unfolded: the others keep their bits.
    let mut whole = TotalField {
        field,
        held,
        scale,
        unfolding: FoldRepair::default(),
    };
    if folds.folded > 0 {
        // Where the warp is held off the bones, the voxels the initial field moves by a bone's
        // motion keep it; tissue carried into a bone's label may move.
        let rigid = bone_map
            .filter(|_| options.bone_margin_mm > 0.0)
            .map(|_| rigid_bones(backend, &initial.field, &initial.residual, labels, bones))
            .transpose()?;
        let held_rigid = (&whole.held, rigid.as_ref());
        let repaired = unfold_registration(
            backend,
            whole.field,
            (&det, &folds),
            held_rigid,
            labels,
            bones,
        )?;
        (whole.field, whole.unfolding) = repaired;
    }
    Ok(whole)
}

/// The outputs of a registration, on the host.
struct Finished {
    field: Field,
    warped: Volume,
    jacobian: Volume,
    inverse: Field,
    inverse_residual: Vec<f32>,
    folds: Folds,
}

/// The whole `field`'s Jacobian and folds (`held` as [`TotalField`]'s), the source resampled
/// once through it and its inverse; all come back together.
fn outputs<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    field: &DeviceImage<B>,
    held: &B::Buffer<f32>,
) -> Result<Finished> {
    let grid = &pair.target.grid;
    let (det, folds) = determinant(backend, field, held)?;
    let resample = ResampleParams::new(&pair.source.grid, grid, 0.0, Interpolation::Linear);
    let warped = backend.resample(&resample, &pair.source.data, &field.data)?;
    let source_grid = &pair.source.grid;
    let (inverse, residual) = invert(backend, field, source_grid)?;
    let wanted = [&field.data, &warped, &det, &inverse.data, &residual];
    let [field, warped, jacobian, inverse, residual] = backend
        .download(&wanted)?
        .try_into()
        .map_err(|_| Error::Gpu("a download returned the wrong number of buffers".into()))?;
    Ok(Finished {
        field: Image::from_data(grid.clone(), bytemuck::cast_vec(field))?,
        warped: Image::from_data(grid.clone(), warped)?,
        jacobian: Image::from_data(grid.clone(), jacobian)?,
        inverse: Image::from_data(source_grid.clone(), bytemuck::cast_vec(inverse))?,
        inverse_residual: residual,
        folds,
    })
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
