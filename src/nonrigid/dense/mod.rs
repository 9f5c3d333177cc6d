//! The dense refinement (beyond the paper): after the adaptive RBF stage, a stationary
//! velocity field per level on the target's finest pyramid levels (three by default), coarse
//! to fine, refines the whole field T to T ∘ exp(v₁) ∘ … ∘ exp(vₙ): each level starts from zero
//! on the field the coarser ones left. Each iteration compares the source seen through the
//! field ∘ exp(v) with the target (SSD or LNCC, shaders/dense/dense_force.wgsl), adds a volume
//! term's force (tissue keeps its volume), smooths the force (fluid) and the velocity
//! (elastic), adds the step (averaged with the previous one: `momentum`), scaled so that no
//! voxel moves further than `step_mm` (at the finest level; more at the coarser ones), holds v
//! at zero on the bones, fading it in over `bone_margin_mm` beyond. exp(v) is taken by scaling
//! and squaring: v / 2ⁿ, small enough to be invertible, composed with itself n times, and
//! where v is zero exp(v) is exactly the identity: every bone keeps exactly its rigid motion
//! (a level's velocity is held again, with the voxels touching the bones, on the target's own
//! grid before its exponential joins the field). The exponential that joins the field is
//! checked on that grid: where it folds (tissue pushed against a held bone), the velocity is
//! faded around the folded voxels until it does not (exponential::unfolded), so each map
//! joining the field has det J > 0 on the grid unless folds outlast every fade (then
//! report.json's `min_det` is ≤ 0 and the log warns). A sparse set of RBF points cannot follow
//! the dense, local deformation of real muscle and fat; this can (greedy's and demons' scheme,
//! with the bones held). Volumes stay where the backend computes; per iteration one cost and
//! the update's largest vectors per chunk come back. A level keeps the velocity whose image
//! term is lowest: where the volume term's steps do not make the scans match better, the level
//! keeps its start.

use crate::abi::dense::{CombineParams, ForceParams, ForceTerm};
use crate::abi::{
    ComposeParams, DilateParams, Interpolation, JacobianParams, LocalMomentsParams, ResampleParams,
    SumParams,
};
use crate::backend::dense::{largest_vectors, smooth, ForceImages};
use crate::backend::{box_sums, resample_onto, totals, Backend, DeviceImage};
use crate::error::Result;
use crate::images::similarity::Similarity;
use crate::images::{pyramid, regions};
use crate::progress::Progress;
use crate::volume::Grid;

pub mod exponential;
mod options;
use exponential::{exponential, squarings, Exponential};
pub use options::DenseOptions;

/// Iterations without progress (see `min_gain`) after which a level stops.
const PATIENCE: usize = 5;

/// What the stage refines, where the backend computes, on the target's grid.
pub struct DenseInputs<'a, B: Backend> {
    /// The source scan, on its own grid.
    pub source: &'a DeviceImage<B>,
    /// The target scan.
    pub target: &'a DeviceImage<B>,
    /// The whole field so far, T (target point → source point, mm).
    pub field: &'a DeviceImage<B>,
    /// The target's voxels that count (1) and those that do not (0).
    pub mask: &'a DeviceImage<B>,
    /// Where the bones are in the target (1 + the bone's position, 0 elsewhere); None: nothing
    /// held.
    pub bones: Option<&'a DeviceImage<B>>,
}

/// What the stage did at one level.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DenseLevel {
    /// Voxels of the level's grid.
    pub dims: [usize; 3],
    /// The image term.
    pub similarity: Similarity,
    /// Iterations run (fewer than asked when the image term stopped falling by `min_gain`).
    pub iterations: usize,
    /// The image term's mean per voxel through the field the level started from.
    pub cost_start: f64,
    /// The same through the velocity kept (the last that lowered it by `min_gain`).
    pub cost_end: f64,
    /// The iteration whose velocity was kept (0: none improved on the start by `min_gain`).
    pub kept_iteration: usize,
}

/// What the stage did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DenseReport {
    /// Each level's figures, coarse to fine.
    pub levels: Vec<DenseLevel>,
    /// Most squarings of a level's exponential on the target's grid.
    pub squarings: u32,
    /// Smallest Jacobian determinant of the levels' exp(v) on the target's grid (1 when no
    /// level kept a step): above 0, the refinement is invertible.
    pub min_det: f32,
    /// Voxels where a level's exp(v) folded on the target's grid (det J ≤ 0) before its
    /// velocity was faded around them ([`exponential::unfolded`]), summed over the fades and
    /// levels; 0: none folded.
    pub folds_faded: usize,
}

/// T refined to T ∘ exp(v₁) ∘ … ∘ exp(vₙ) (on the target's grid), one stationary velocity per
/// level, coarse to fine, and what the stage did. Each level refines the field the coarser ones
/// left, from a zero velocity, so that the finest level's velocity, and with it the squarings
/// each of its evaluations takes, stays as short as what that level adds.
pub fn refine<B: Backend>(
    backend: &B,
    inputs: &DenseInputs<B>,
    options: &DenseOptions,
    progress: &dyn Progress,
) -> Result<(DeviceImage<B>, DenseReport)> {
    options.check()?;
    let targets = pyramid::build(backend, inputs.target.clone(), options.levels)?;
    let sources = pyramid::build(backend, inputs.source.clone(), targets.len())?;
    let margin = options.bone_margin_mm;
    // Held on the target's own grid with a ring ([`distance_beyond_the_bones`]), where every
    // level's exp(v) is taken: the finest level's hold.
    let held_here = held_map(backend, inputs.bones, &inputs.field.grid, margin, 1)?;
    let mut field = inputs.field.clone();
    let mut report = DenseReport {
        levels: Vec::new(),
        squarings: 0,
        min_det: 1.0,
        folds_faded: 0,
    };
    for (index, target) in targets.iter().enumerate().rev() {
        let source = &sources[index.min(sources.len() - 1)];
        let held = match index {
            0 => held_here.clone(),
            _ => held_map(backend, inputs.bones, &target.grid, margin, 0)?,
        };
        let level = Level::new(backend, (&field, inputs.mask), target, source, held)?;
        let name = format!("dense refinement, level {}", targets.len() - index);
        progress.begin(&name, options.iterations.at_level(index));
        let coarser = target.grid.finest_spacing() / targets[0].grid.finest_spacing();
        let settings = LevelSettings::of(options, index, coarser);
        let (kept, done) = level.run(backend, &settings, progress)?;
        progress.end();
        if done.kept_iteration > 0 {
            let (refined, exp) = composed(backend, &field, &held_here, kept)?;
            field = refined;
            report.join(&exp);
            say_kept(progress, &name, &done, &exp);
        } else {
            progress.say(&format!(
                "{name}: no step lowered the image term by min_gain; the field is kept"
            ));
        }
        report.levels.push(done);
    }
    Ok((field, report))
}

impl DenseReport {
    /// Counts in a level's exponential, now part of the field.
    fn join<B: Backend>(&mut self, exp: &Exponential<B>) {
        self.squarings = self.squarings.max(exp.squarings);
        self.min_det = self.min_det.min(exp.folds.min);
        self.folds_faded += exp.faded;
    }
}

/// The log's line on what level `name` kept and how its exponential came out; a warning where
/// it still folds after every fade (the finish's unfolding then lifts the folds).
fn say_kept<B: Backend>(
    progress: &dyn Progress,
    name: &str,
    done: &DenseLevel,
    exp: &Exponential<B>,
) {
    let kept = format!(
        "iteration {} of {} kept, image term {:.4} -> {:.4}",
        done.kept_iteration, done.iterations, done.cost_start, done.cost_end
    );
    let det = format!("exp(v) min det J {:.4}", exp.folds.min);
    progress.say(&match exp.fades {
        0 => format!("{name}: {kept}; {det}"),
        fades => format!(
            "{name}: {kept} (before fading); {det} after {fades} fade(s) around folded voxels \
             ({} before them)",
            exp.faded
        ),
    });
    if exp.folds.folded > 0 {
        progress.warn(&format!(
            "{name}: exp(v) still folds at {} voxels after {} fades (min det J {:.4}); \
             the finish's unfolding lifts what is left",
            exp.folds.folded, exp.fades, exp.folds.min
        ));
    }
}

/// `field` ∘ exp(v) on `field`'s grid, v (a level's velocity on its own grid, its vectors at
/// most `bound` mm long) sampled there and, from a coarser grid, held where `held` says; with
/// the exponential taken, faded where it folded ([`exponential::unfolded`]).
fn composed<B: Backend>(
    backend: &B,
    field: &DeviceImage<B>,
    held: &Held<B>,
    (v, bound): (DeviceImage<B>, f64),
) -> Result<(DeviceImage<B>, Exponential<B>)> {
    let grid = &field.grid;
    // The finest level's velocity was held with `held` itself at its every step: fading it
    // again would shrink it over the margin, away from the velocity the level evaluated.
    let v = if v.grid.same_as(grid, 0.0) {
        v.data
    } else {
        let sampled = sampled_field(backend, &v, grid)?;
        combine(backend, grid, held, (1.0, &sampled), (0.0, &sampled))?
    };
    let exp = exponential::unfolded(backend, grid, v, bound)?;
    let params = ComposeParams::new(grid, grid);
    let refined = DeviceImage {
        data: backend.compose(&params, &exp.map.data, &field.data)?,
        grid: grid.clone(),
    };
    Ok((refined, exp))
}

/// One level's settings.
struct LevelSettings {
    iterations: usize,
    similarity: Similarity,
    radius: usize,
    fluid_sigma: f64,
    elastic_sigma: f64,
    /// This level's step (mm): `step_mm` times its voxels' size against the finest level's.
    step_mm: f64,
    volume_weight: f64,
    momentum: f64,
    min_gain: f64,
}

impl LevelSettings {
    /// The settings at pyramid level `index` (0 the finest), whose voxels are `coarser` times
    /// the finest level's.
    fn of(options: &DenseOptions, index: usize, coarser: f64) -> Self {
        LevelSettings {
            iterations: options.iterations.at_level(index),
            similarity: options.similarity.at_level(index),
            radius: options.lncc_radius.at_level(index),
            fluid_sigma: options.fluid_sigma.at_level(index),
            elastic_sigma: options.elastic_sigma.at_level(index),
            step_mm: options.step_mm * coarser,
            volume_weight: options.volume_weight.at_level(index),
            momentum: options.momentum.at_level(index),
            min_gain: options.min_gain,
        }
    }
}

/// The images of one level, on its grid.
struct Level<B: Backend> {
    /// The target at this level (F).
    target: DeviceImage<B>,
    /// The source at the matching level of its own pyramid.
    source: DeviceImage<B>,
    /// T sampled at this level's voxels.
    field: B::Buffer<f32>,
    /// The target mask at this level.
    mask: B::Buffer<f32>,
    /// Where the velocity is held at this level.
    held: Held<B>,
}

impl<B: Backend> Level<B> {
    /// The level on `target`'s grid: the field so far and the target mask sampled there, the
    /// velocity held where `held` says.
    fn new(
        backend: &B,
        (field, mask): (&DeviceImage<B>, &DeviceImage<B>),
        target: &DeviceImage<B>,
        source: &DeviceImage<B>,
        held: Held<B>,
    ) -> Result<Self> {
        let grid = &target.grid;
        Ok(Level {
            target: target.clone(),
            source: source.clone(),
            field: sampled_field(backend, field, grid)?,
            mask: nearest_onto(backend, mask, grid)?,
            held,
        })
    }

    fn grid(&self) -> &Grid {
        &self.target.grid
    }

    /// The level's iterations from a zero velocity: the velocity with the lowest image term met
    /// (by at least `min_gain` each time), with a bound on its length (mm), and what was done.
    fn run(
        &self,
        backend: &B,
        settings: &LevelSettings,
        progress: &dyn Progress,
    ) -> Result<((DeviceImage<B>, f64), DenseLevel)> {
        let grid = self.grid();
        let update_sigma = settings.fluid_sigma.hypot(settings.elastic_sigma);
        let (mut v, mut bound) = (backend.zeros("velocity", 3 * grid.len())?, 0.0);
        let mut kept = (v.clone(), bound, f64::INFINITY, 0);
        let (mut cost_start, mut ran, mut previous) = (f64::NAN, 0, None);
        for iteration in 0..=settings.iterations {
            // The volume term steers the steps; the image term alone decides what is kept.
            let (force, cost) = self.evaluate(backend, &v, bound, settings)?;
            if iteration == 0 {
                cost_start = cost;
            }
            if iteration == 0 || cost < kept.2 - settings.min_gain * kept.2.abs() {
                kept = (v.clone(), bound, cost, iteration);
            }
            let stalled = iteration >= kept.3 + PATIENCE;
            if iteration == settings.iterations || stalled {
                break;
            }
            let update = smooth(backend, grid, 3, update_sigma, &force)?;
            let update = match previous {
                Some(previous) if settings.momentum > 0.0 => {
                    let memory =
                        CombineParams::sum(grid, 1.0 - settings.momentum, settings.momentum);
                    backend.field_combine(&memory, &update, &previous, &update)?
                }
                _ => update,
            };
            let smoothed = smooth(backend, grid, 3, settings.elastic_sigma, &v)?;
            let [largest, length] = largest_vectors(backend, grid, &[&update, &smoothed])?[..]
            else {
                unreachable!("two fields measured")
            };
            progress.step(&format!("cost {cost:.6}"));
            if largest <= 0.0 {
                break;
            }
            v = combine(
                backend,
                grid,
                &self.held,
                (1.0, &smoothed),
                (settings.step_mm / largest as f64, &update),
            )?;
            previous = Some(update);
            ran = iteration + 1;
            // Fading never lengthens a vector; the step adds at most its size.
            bound = length as f64 + settings.step_mm;
        }
        let (v, bound, cost_end, kept_iteration) = kept;
        let done = DenseLevel {
            dims: grid.dims,
            similarity: settings.similarity,
            iterations: ran,
            cost_start,
            cost_end,
            kept_iteration,
        };
        let v = DeviceImage {
            data: v,
            grid: grid.clone(),
        };
        Ok(((v, bound), done))
    }

    /// The force (3 floats per voxel: the image term's, plus the volume term's times its
    /// weight) and the image term's mean cost per voxel through T ∘ exp(v). The cost leaves
    /// the volume term out: a level keeps a velocity only where the scans match better
    /// through it. Kept on the sum of both, the coarse levels traded image match for volume
    /// where the image has little to hold (the half phantom at 60°, whose truth squeezes a
    /// fifth of its soft tissue, 0.76 mm without the coarse levels, 1.64 with them; now their
    /// start is kept and it is 0.76), while on the knee pairs whose truth keeps tissue volume
    /// the image follows the volume term (2 mm 90°, one velocity through the levels: 5.26 mm
    /// kept on the sum, 5.55 on the image; BENCHMARKS.md, thirty-sixth session).
    fn evaluate(
        &self,
        backend: &B,
        v: &B::Buffer<f32>,
        bound: f64,
        settings: &LevelSettings,
    ) -> Result<(B::Buffer<f32>, f64)> {
        let grid = self.grid();
        let phi = exponential(backend, grid, v, squarings(bound, grid))?;
        let whole = backend.compose(&ComposeParams::new(grid, grid), &phi, &self.field)?;
        let sampling = ResampleParams::new(&self.source.grid, grid, 0.0, Interpolation::Linear);
        let moving = backend.resample(&sampling, &self.source.data, &whole)?;
        let covered = backend.coverage(&sampling, &whole, &self.mask)?;
        let (term, sums) = match settings.similarity {
            Similarity::Ssd => (ForceTerm::Ssd, moving.clone()),
            Similarity::Lncc => {
                let passes = LocalMomentsParams::passes(grid, settings.radius);
                (
                    ForceTerm::Lncc,
                    box_sums(backend, &passes, &moving, &self.target.data)?,
                )
            }
        };
        let images = ForceImages {
            moving: &moving,
            fixed: &self.target.data,
            covered: &covered,
            sums: &sums,
        };
        let params = ForceParams::new(grid, term, settings.radius);
        let (force, cost) = backend.dense_force(&params, &images)?;
        let cost = means(backend, grid, &[&cost])?[0];
        match settings.volume_weight {
            0.0 => Ok((force, cost)),
            weight => {
                let volume = self.volume_force(backend, &whole, &covered)?;
                let sum = CombineParams::sum(grid, 1.0, weight);
                Ok((backend.field_combine(&sum, &force, &volume, &force)?, cost))
            }
        }
    }

    /// The volume term's force per voxel for the whole map `whole` (ForceTerm::Volume) where
    /// `covered`.
    fn volume_force(
        &self,
        backend: &B,
        whole: &B::Buffer<f32>,
        covered: &B::Buffer<f32>,
    ) -> Result<B::Buffer<f32>> {
        let grid = self.grid();
        let det = backend.jacobian(&JacobianParams::new(grid), whole)?;
        let images = ForceImages {
            moving: &det,
            fixed: &det,
            covered,
            sums: &det,
        };
        let params = ForceParams::new(grid, ForceTerm::Volume, 0);
        // The kernel also gives the term's cost per voxel; a level's choice leaves it out.
        Ok(backend.dense_force(&params, &images)?.0)
    }
}

/// The distance (mm) to the nearest held voxel and the margin over which the velocity rises
/// beyond it; None: nothing held.
type Held<B> = Option<(<B as crate::backend::Core>::Buffer<f32>, f64)>;

/// Where the velocity is held on `grid`: on `bones` (a bone index per voxel, on its own grid)
/// grown by `rings` voxels, rising to its whole `margin_mm` beyond; nothing without bones or
/// margin.
fn held_map<B: Backend>(
    backend: &B,
    bones: Option<&DeviceImage<B>>,
    grid: &Grid,
    margin_mm: f64,
    rings: usize,
) -> Result<Held<B>> {
    match bones.filter(|_| margin_mm > 0.0) {
        Some(map) => {
            let map = nearest_onto(backend, map, grid)?;
            let distance = distance_beyond_the_bones(backend, grid, map, rings)?;
            Ok(Some((distance, margin_mm)))
        }
        None => Ok(None),
    }
}

/// fade · (a_scale · a + b_scale · b) on `grid`, faded where `held` says.
fn combine<B: Backend>(
    backend: &B,
    grid: &Grid,
    held: &Held<B>,
    (a_scale, a): (f64, &B::Buffer<f32>),
    (b_scale, b): (f64, &B::Buffer<f32>),
) -> Result<B::Buffer<f32>> {
    let params = CombineParams::sum(grid, a_scale, b_scale);
    match held {
        Some((distance, margin)) => backend.field_combine(&params.faded(*margin), a, b, distance),
        None => backend.field_combine(&params, a, b, a),
    }
}

/// The mean of each of `values` (one per voxel of `grid`), reduced where the backend
/// computes; the sums come back together, with one wait.
fn means<B: Backend>(backend: &B, grid: &Grid, values: &[&B::Buffer<f32>]) -> Result<Vec<f64>> {
    let totals = totals(backend, &SumParams::new(grid.len()), values)?;
    Ok(totals.iter().map(|t| t / grid.len() as f64).collect())
}

/// The distance (mm) from the bones (`bones`: a bone index per voxel, 0 off the bones) grown
/// by `rings` voxels, 0 on them. One ring at the finest level holds the velocity at zero on
/// every voxel touching a bone too, so that, sampled trilinearly, it is zero over each bone
/// voxel's whole cell and no tissue is carried into a bone's voxels. Held on the bones alone
/// it was: through the field, the small phantom's patella (20°) covered 523 target voxels
/// against its rigid motion's 492 and the truth's 488, the 2 mm 90° knee's femur 649 voxels
/// more than the truth's against 142 without the stage. The coarser levels' velocities are
/// held again with the ring on the target's own grid before their exponentials join the
/// field, so at their own grids they keep the bones alone: a ring of their 4 and 8 mm voxels
/// held the tissue near the bones back (BENCHMARKS.md, thirty-fifth session).
fn distance_beyond_the_bones<B: Backend>(
    backend: &B,
    grid: &Grid,
    bones: B::Buffer<f32>,
    rings: usize,
) -> Result<B::Buffer<f32>> {
    let mut grown = bones;
    if rings > 0 {
        for mut pass in DilateParams::passes(grid, rings) {
            // Nothing is cleared, so the held voxels (the third argument) are not read.
            pass.clear_held = 0;
            grown = backend.dilate(&pass, &grown, &grown)?;
        }
    }
    let grown = DeviceImage {
        data: grown,
        grid: grid.clone(),
    };
    regions::distance_to_nearest(backend, &grown)
}

/// `field` (3 floats per voxel) sampled at `grid`'s voxels (itself on its own grid).
fn sampled_field<B: Backend>(
    backend: &B,
    field: &DeviceImage<B>,
    grid: &Grid,
) -> Result<B::Buffer<f32>> {
    if field.grid.same_as(grid, 0.0) {
        return Ok(field.data.clone());
    }
    // u = 0 + field ∘ (id + 0): the composition samples the second field at the first's grid.
    let still = backend.zeros("zero displacement", 3 * grid.len())?;
    backend.compose(&ComposeParams::new(grid, &field.grid), &still, &field.data)
}

/// `image` at `grid`'s voxels, nearest voxel (label and mask maps; itself on its own grid).
fn nearest_onto<B: Backend>(
    backend: &B,
    image: &DeviceImage<B>,
    grid: &Grid,
) -> Result<B::Buffer<f32>> {
    if image.grid.same_as(grid, 0.0) {
        return Ok(image.data.clone());
    }
    Ok(resample_onto(backend, image, grid, Interpolation::Nearest)?.data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_level_reads_the_defaults_from_the_finest_up() {
        let options = DenseOptions {
            levels: 4,
            ..Default::default()
        };
        let read = |index, coarser| {
            let s = LevelSettings::of(&options, index, coarser);
            (s.iterations, s.fluid_sigma, s.momentum, s.step_mm)
        };
        assert_eq!(read(0, 1.0), (30, 2.0, 0.25, 2.0), "the finest level");
        assert_eq!(read(2, 4.0), (100, 3.0, 0.5, 8.0));
        assert_eq!(
            read(3, 8.0),
            (100, 3.0, 0.5, 16.0),
            "a fourth repeats the coarsest"
        );
    }
}
