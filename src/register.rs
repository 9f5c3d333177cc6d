//! The whole pipeline, generic over the backend: articulated initialisation (optional), the
//! adaptive cubic-RBF stage, the composed field, a fold check, and the source resampled once.

use crate::abi::Interpolation;
use crate::adaptive::{self, Adaptive, AdaptiveOptions, Moving};
use crate::articulated::{initialise, InitOptions, Initialisation};
use crate::backend::{resample_onto, Backend, Traffic};
use crate::error::Result;
use crate::evaluate::seen_by_both;
use crate::fold_repair::{maps_into_bone, unfold_registration, FoldRepair};
use crate::progress::Progress;
use crate::volume::{Field, Grid, Image, Labels, Volume};
use nalgebra::Vector3;

/// Settings of a registration: what a config file holds (io::config), every field optional
/// there.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RegisterOptions {
    /// Run the articulated initialisation; false is the paper's first experiment (small bends).
    pub initialise: bool,
    /// Articulated initialisation settings.
    pub init: InitOptions,
    /// The adaptive stage.
    pub adaptive: AdaptiveOptions,
    /// Control points held at zero added displacement on each bone's surface.
    pub pins_per_bone: usize,
}

impl Default for RegisterOptions {
    fn default() -> Self {
        RegisterOptions {
            initialise: true,
            init: InitOptions::default(),
            adaptive: AdaptiveOptions::default(),
            pins_per_bone: 8,
        }
    }
}

impl crate::io::config::Settings for RegisterOptions {
    fn check(&self) -> Result<()> {
        RegisterOptions::check(self)
    }
}

impl RegisterOptions {
    /// Rejects settings the registration cannot run with, naming the setting.
    pub fn check(&self) -> Result<()> {
        self.init.check()?;
        self.adaptive.check()?;
        // Each pin is a control point of the dense RBF system: thousands would stall it.
        if self.pins_per_bone > MAX_PINS_PER_BONE {
            return Err(crate::Error::InvalidInput(format!(
                "pins_per_bone must be 0 to {MAX_PINS_PER_BONE}"
            )));
        }
        Ok(())
    }
}

/// Most pins a bone may get (`pins_per_bone`).
const MAX_PINS_PER_BONE: usize = 64;

/// What a registration produces.
pub struct Registration {
    /// The articulated initialisation, when run.
    pub init: Option<Initialisation>,
    /// The adaptive stage.
    pub adaptive: Adaptive,
    /// Total field: target point → source point (RAS mm).
    pub field: Field,
    /// The source resampled once through it.
    pub warped: Volume,
    /// Smallest Jacobian determinant of the field over the target.
    pub min_jacobian: f32,
    /// Share of target voxels with determinant ≤ 0.
    pub folded_share: f64,
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
    /// Articulated initialisation.
    pub initialisation: Traffic,
    /// Adaptive RBF stage.
    pub adaptive: Traffic,
    /// Composition, fold check and the final resampling.
    pub finish: Traffic,
    /// The three together.
    pub total: Traffic,
}

/// Seconds spent in each stage of a registration.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StageTimes {
    /// Articulated initialisation (0 when skipped).
    pub initialisation: f64,
    /// Adaptive RBF stage.
    pub adaptive: f64,
    /// Composition, fold check and the final resampling.
    pub finish: f64,
}

/// Up to `per_bone` points on each bone's surface in the target: boundary voxels of the region
/// that the initial field maps into the bone, spread by farthest-point sampling.
pub fn bone_pins(
    initial: &Field,
    labels: &Labels,
    bones: &[u16],
    per_bone: usize,
) -> Vec<Vector3<f64>> {
    let grid = &initial.grid;
    let d = grid.dims;
    let mut pins = Vec::new();
    for &bone in bones {
        let inside = maps_into_bone(initial, labels, &[bone]);
        let boundary: Vec<usize> = (0..grid.len())
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
            .collect();
        let points: Vec<Vector3<f64>> = boundary.iter().map(|&n| grid.world_of(n)).collect();
        let Some(first) = points.first() else {
            continue;
        };
        let mut chosen = vec![*first];
        let mut nearest: Vec<f64> = points.iter().map(|p| (p - first).norm()).collect();
        while chosen.len() < per_bone {
            let (k, far) =
                nearest
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
        pins.extend(chosen);
    }
    pins
}

/// 1 on the voxels of `field`'s grid whose source point (p + u) lies inside `source`'s field of
/// view, else 0.
pub fn coverage(field: &Field, source: &Grid) -> Volume {
    Image {
        grid: field.grid.clone(),
        data: seen_by_both(field, source, -0.5)
            .into_iter()
            .map(|inside| inside as u8 as f32)
            .collect(),
    }
}

/// Registers `source` (with its bone `labels`) to `target`.
pub fn register<B: Backend>(
    backend: &B,
    source: &Volume,
    labels: &Labels,
    target: &Volume,
    options: &RegisterOptions,
    progress: &dyn Progress,
) -> Result<Registration> {
    let clock = std::time::Instant::now();
    let at_start = backend.traffic();
    options.check()?;
    let (init, initial, moving) = match options.initialise.then_some(&options.init) {
        Some(init_options) => {
            let init = initialise(
                backend,
                source,
                labels,
                target,
                init_options,
                None,
                progress,
            )?;
            let field = init.initial.field.clone();
            let moving = init.initialised.clone();
            (Some(init), field, moving)
        }
        None => {
            let moving = resample_onto(backend, source, &target.grid)?;
            (
                None,
                Image::filled(target.grid.clone(), [0.0f32; 3]),
                moving,
            )
        }
    };
    let pins = match &init {
        Some(i) if options.pins_per_bone > 0 => {
            bone_pins(&initial, labels, &i.weights.bones, options.pins_per_bone)
        }
        _ => Vec::new(),
    };
    let initialisation = clock.elapsed().as_secs_f64();
    let after_init = backend.traffic();
    let coverage = coverage(&initial, &source.grid);
    let adaptive = adaptive::register(
        backend,
        &Moving {
            image: &moving,
            coverage: &coverage,
            prealigned: init.is_some(),
        },
        target,
        &pins,
        &options.adaptive,
        progress,
    )?;
    let adaptive_seconds = clock.elapsed().as_secs_f64() - initialisation;
    let after_adaptive = backend.traffic();
    // Step control: the added warp itself must not fold; while it does, shrink it. Folds of
    // the initial field (skinning at large angles) are carried into the total field and
    // reported, but are not the warp's to undo. (Counting the total field's folds instead
    // threw away 94% of a good warp at 60° over one voxel sampled differently inside the
    // initial field's fold: 1.34 → 1.77 mm.)
    progress.begin("composition and resampling", 1);
    let folds = |det: &Volume| det.data.iter().filter(|&&v| v <= 0.0).count();
    let mut scale = 1.0;
    let warp = loop {
        let warp =
            adaptive.warp_field(backend, &target.grid, options.adaptive.lattice_mm, scale)?;
        if folds(&backend.jacobian(&warp)?) == 0 || scale < 0.1 {
            break warp;
        }
        scale *= 0.5;
    };
    let mut field = backend.compose(&warp, &initial)?;
    let mut det = backend.jacobian(&field)?;
    // Only a field that folds is unfolded: the others keep their bits.
    let mut unfolding = FoldRepair::default();
    if det.data.iter().any(|&d| d <= 0.0) {
        let bones = init.as_ref().map_or(&[][..], |i| &i.weights.bones[..]);
        unfolding = unfold_registration(backend, &mut field, &det, labels, bones)?;
        det = backend.jacobian(&field)?;
    }
    let warped = backend.resample(source, &field, 0.0, Interpolation::Linear)?;
    progress.step(&format!("warp scale {scale}"));
    progress.end();
    let timings = StageTimes {
        initialisation,
        adaptive: adaptive_seconds,
        finish: clock.elapsed().as_secs_f64() - initialisation - adaptive_seconds,
    };
    let at_end = backend.traffic();
    let traffic = StageTraffic {
        initialisation: after_init - at_start,
        adaptive: after_adaptive - after_init,
        finish: at_end - after_adaptive,
        total: at_end - at_start,
    };
    let min_jacobian = det.data.iter().cloned().fold(f32::INFINITY, f32::min);
    let folded_share = folds(&det) as f64 / det.data.len() as f64;
    Ok(Registration {
        init,
        adaptive,
        field,
        warped,
        min_jacobian,
        folded_share,
        warp_scale: scale,
        unfolding,
        timings,
        traffic,
    })
}

impl Registration {
    /// The registration in the bone-transform format: bone motions (none without the
    /// initialisation) plus the RBF stage's control points and solved coefficients, and how
    /// the total field is composed. field.nii.gz beside it holds that total field sampled on the
    /// target grid.
    pub fn transforms(&self, options: &RegisterOptions) -> crate::io::transform::BoneTransforms {
        let mut transform = self
            .init
            .as_ref()
            .map(|i| i.transforms())
            .unwrap_or_else(|| crate::io::transform::BoneTransforms::new(Vec::new()));
        transform.extra.insert(
            "rbf".into(),
            serde_json::json!({
                "basis": "cubic, phi(r) = r^3, world RAS mm, on the target grid",
                "lattice_mm": options.adaptive.lattice_mm,
                "control_points": self.adaptive.points,
                "coefficients": self.adaptive.coefficients,
                "scale": self.warp_scale,
                "composition": "u(x) = R(x) + u0(x + R(x)); u0 = inverted skinning of the bone motions",
                "unfolding": self.unfolding,
            }),
        );
        transform
    }
}
