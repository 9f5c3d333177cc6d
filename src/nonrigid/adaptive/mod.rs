//! Adaptive non-rigid registration (paper §3): cubic-RBF control points are added only in the
//! cells that still fit poorly, from 2×2×2 cells up to 16×16×16, over a pyramid coarse to fine,
//! and their displacements optimised by L-BFGS on the sum of squared differences, or per level
//! on local correlation (crate::images::similarity), plus, after the articulated initialisation, the
//! membrane energy of the added warp (crate::nonrigid::regularise).
//!
//! Cost: the warp is evaluated on a coarse lattice (about every 5 mm) — nodes × control points,
//! not voxels × control points — and interpolated per voxel; the gradient comes back through the
//! adjoint of that interpolation (lattice_splat), the RBF's adjoint at the nodes and the solved
//! system (RbfSystem::value_gradient). Each evaluation is one pass of kernels on the backend's
//! buffers (`Evaluator`): only the coefficients go up and only the gradient with respect to
//! them and a few partial sums come back. The per-refinement warped image, its cell costs and
//! the intensity gain stay on the device too: only the per-cell sums come back. The pyramids are
//! built there from one upload of the target, the moving image and its coverage. During
//! optimisation the moving image is
//! the initialised source I0 on the target grid; the final field is composed with the initial
//! field, u = R + u0 ∘ (id + R), and the source resampled once through it.

mod evaluator;
mod options;

pub use options::AdaptiveOptions;

use evaluator::{Evaluator, Lattice, Level};

use crate::abi::{Interpolation, RbfGradParams, SsdParams, SumParams};
use crate::backend::{resample_onto, total, Backend, DeviceImage, Traffic};
use crate::error::Result;
use crate::images::metric::{check_cells, fold_ssd_partials, CellSsd};
use crate::images::pyramid;
use crate::images::similarity::{LnccCost, Similarity};
use crate::nonrigid::gain::gain;
use crate::nonrigid::optim::lbfgs;
use crate::nonrigid::rbf::{RbfCoefficients, RbfSystem};
use crate::progress::Progress;
use crate::volume::Grid;
use nalgebra::Vector3;

/// New points a refinement needs before it optimises (fewer wait for the level's next
/// refinement): each optimisation costs its level's L-BFGS run whatever the points it adds,
/// and one to three new points in coarse cells lowered the cost little for a whole run at the
/// finest level. Measured with the L-BFGS change beside it on the knee pairs and the half
/// phantoms (BENCHMARKS.md, sixteenth session): most pairs within 0.01 mm, one 0.05 mm worse.
const FEWEST_TO_OPTIMISE: usize = 4;

/// One control point.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ControlPoint {
    /// Position (target world, RAS mm).
    pub position: [f64; 3],
    /// Displacement R at the point (mm).
    pub displacement: [f64; 3],
    /// Pinned points keep zero added displacement (bone surfaces, already aligned).
    pub pinned: bool,
    /// Cells per axis when it was added (0 for pins).
    pub cells: usize,
}

/// One refinement's record.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StageReport {
    /// Pyramid level (0 finest).
    pub level: usize,
    /// Cells per axis.
    pub cells: [usize; 3],
    /// Points added (with any that earlier refinements of the level added and left to it).
    pub added: usize,
    /// The cost's image term.
    pub similarity: Similarity,
    /// The cost (image term and regularisers) before and after.
    pub cost_before: f64,
    /// After optimisation.
    pub cost_after: f64,
    /// L-BFGS iterations.
    pub iterations: usize,
}

/// The adaptive stage's outcome.
pub struct Adaptive {
    /// All control points.
    pub points: Vec<ControlPoint>,
    /// The solved warp.
    pub coefficients: RbfCoefficients,
    /// The grid of the finest level (the target's), and its lattice's step along each axis
    /// (voxels of that grid): R is evaluated at the lattice's nodes and interpolated between
    /// them.
    pub lattice: (Grid, [usize; 3]),
    /// Record per refinement that optimised.
    pub stages: Vec<StageReport>,
    /// What the optimiser's cost evaluations moved between host and device.
    pub evaluations: Evaluations,
}

/// The optimiser's cost-and-gradient evaluations and their traffic.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct Evaluations {
    /// Evaluations over the whole stage.
    pub count: usize,
    /// Their traffic together.
    pub traffic: Traffic,
    /// The most bytes one evaluation read back.
    pub most_bytes_down: u64,
}

impl Evaluations {
    /// Counts one evaluation that moved `traffic`.
    fn add(&mut self, traffic: Traffic) {
        self.count += 1;
        self.most_bytes_down = self.most_bytes_down.max(traffic.bytes_down);
        self.traffic += traffic;
    }
}

/// `wanted` cells per axis on `grid`, fewer where an axis has fewer than `min_voxels` voxels
/// per cell.
fn cells_on(grid: &Grid, wanted: usize, min_voxels: usize) -> [usize; 3] {
    std::array::from_fn(|a| wanted.min(grid.dims[a] / min_voxels).max(1))
}

/// The lattice's step (voxels) along each axis of a level's `grid`: `lattice_mm` at the grid's
/// finest spacing, or, once the moving image is `prealigned` by the initialisation, half the
/// side of the level's finest cells along an axis where that is coarser. After the
/// initialisation R is a correction, a sum of cubic radial functions centred a cell or more
/// apart and smooth on the scale of a cell, and its nodes cost one f64 square root per control
/// point each: on the half phantom, whose finest cells are 10.6 × 20 × 19 mm, a 5 mm lattice
/// had 4× the nodes and no more accuracy than half a cell. Without the initialisation R
/// carries the joint's whole motion, bent at the joint, and wants the finer lattice (paper
/// phantom 10°: 1.38 → 1.45 mm at half a cell; BENCHMARKS.md, fourteenth session).
pub fn lattice_steps(grid: &Grid, options: &AdaptiveOptions, prealigned: bool) -> [usize; 3] {
    let finest = ((options.lattice_mm / grid.finest_spacing()).round() as usize).max(1);
    if !prealigned {
        return [finest; 3];
    }
    let wanted = options.cell_levels.iter().copied().max().unwrap_or(1);
    let cells = cells_on(grid, wanted, options.min_cell_voxels);
    std::array::from_fn(|a| {
        let half_cell = grid.dims[a] as f64 / cells[a] as f64 / 2.0;
        finest.max(half_cell.round() as usize)
    })
}

/// Population variance of an image's intensities, reduced where the backend computes: the
/// mean, then the squares about it.
fn variance<B: Backend>(backend: &B, image: &DeviceImage<B>) -> Result<f64> {
    let n = image.grid.len();
    let mean = total(backend, &SumParams::new(n), &image.data)? / n as f64;
    let shift = mean as f32;
    let squares = total(backend, &SumParams::squares_about(n, shift), &image.data)? / n as f64;
    Ok(squares - (mean - shift as f64).powi(2))
}

/// Centre (world) of cell `c` of a grid split into `cells`.
fn cell_centre(grid: &Grid, cells: [usize; 3], c: [usize; 3]) -> Vector3<f64> {
    let ijk: [f64; 3] = std::array::from_fn(|a| {
        let lo = (c[a] * grid.dims[a]).div_ceil(cells[a]) as f64;
        let hi = ((c[a] + 1) * grid.dims[a]).div_ceil(cells[a]) as f64 - 1.0;
        (lo + hi) / 2.0
    });
    let w = grid.voxel_to_world(ijk);
    Vector3::new(w[0], w[1], w[2])
}

/// The warp interpolating the control points' displacements, and their positions.
fn solve(points: &[ControlPoint], smoothing: f64) -> Result<(RbfCoefficients, Vec<Vector3<f64>>)> {
    let centres: Vec<Vector3<f64>> = points.iter().map(|p| Vector3::from(p.position)).collect();
    let values: Vec<Vector3<f64>> = points
        .iter()
        .map(|p| Vector3::from(p.displacement))
        .collect();
    let coefficients = RbfSystem::new(centres.clone(), smoothing)?.coefficients(&values)?;
    Ok((coefficients, centres))
}

/// The warp of the control points as they stand and the moving image seen through it.
struct Warped<B: Backend> {
    coef: RbfCoefficients,
    centres: Vec<Vector3<f64>>,
    image: B::Buffer<f32>,
}

/// The control points' warp and `moving` seen through it on the lattice's grid.
fn warp_moving<B: Backend>(
    backend: &B,
    points: &[ControlPoint],
    smoothing: f64,
    lattice: &Lattice<B>,
    moving: &B::Buffer<f32>,
) -> Result<Warped<B>> {
    let (coef, centres) = solve(points, smoothing)?;
    let warp = lattice.warp(backend, &coef, &centres)?;
    let image = backend.warp_image(&lattice.voxel_params, &warp.values, moving)?;
    Ok(Warped {
        coef,
        centres,
        image,
    })
}

/// The mean squared residual per cell of `level`'s grid split into `cells`, counting only
/// voxels where the moving image holds data.
fn cell_costs<B: Backend>(
    backend: &B,
    level: &Level<B>,
    warped: &B::Buffer<f32>,
    cells: [usize; 3],
) -> Result<CellSsd> {
    let dims = level.fixed.grid.dims;
    check_cells(dims, cells)?;
    let partial = backend.ssd_cells(&SsdParams::new(dims, cells), &level.images(warped))?;
    let partial = backend.download_one(&partial)?;
    Ok(fold_ssd_partials(dims, cells, &partial))
}

/// What the adaptive stage deforms: the source on the target grid, where the backend computes.
pub struct Moving<'a, B: Backend> {
    /// The source (initialised, or just resampled) on the target grid.
    pub image: &'a DeviceImage<B>,
    /// 1 where `image` holds data from the source scan, 0 where its sample fell outside the
    /// source's field of view (there it reads background, which is not the anatomy).
    pub coverage: &'a DeviceImage<B>,
    /// Whether the articulated initialisation aligned it.
    pub prealigned: bool,
    /// Share of the target grid the user's target mask holds (1 without one): the voxels a
    /// cell's residual is weighed against.
    pub mask_share: f64,
}

/// Residuals where the moving image has no data from the source are not evidence: the cost
/// leaves them out. Measured on the paper phantom at 10° with the initialisation: counting them,
/// the adaptive stage pulled the tissue at the bottom of the field of view (where the turned
/// shank's source lies below the straight scan) from 0.6 to 4.4 mm of error (0.98 → 0.53 mm
/// mean). The coverage is the initial one, per level; the kernels count a voxel as covered
/// where its level's coverage is at least abi::COVERED_AT (the pyramid's smoothing erodes it at
/// coarse levels). Coverage re-measured through the warp was tried and is worse: the
/// optimiser then hides mismatches by pulling samples off the grid (10° without
/// initialisation, 1.34 → 1.59 mm).
fn levels<B: Backend>(
    backend: &B,
    moving: &Moving<B>,
    target: &DeviceImage<B>,
    (count, finest_stride): (usize, usize),
) -> Result<Vec<Level<B>>> {
    let mut fixed = pyramid::build(backend, target.clone(), count)?;
    let count = fixed.len();
    let moving_levels = pyramid::build(backend, moving.image.clone(), count)?;
    let mut covered = pyramid::build(backend, moving.coverage.clone(), count)?;
    // The finest level's target and coverage on every finest_stride-th voxel: the voxels
    // themselves, not smoothed (the moving image keeps its full resolution).
    if finest_stride > 1 {
        let sampled = target.grid.every(finest_stride);
        let nearest = |image: &DeviceImage<B>| {
            resample_onto(backend, image, &sampled, Interpolation::Nearest)
        };
        (fixed[0], covered[0]) = (nearest(&fixed[0])?, nearest(&covered[0])?);
    }
    let share = moving.mask_share;
    Ok(fixed
        .into_iter()
        .zip(moving_levels)
        .zip(covered)
        .enumerate()
        .map(|(index, ((fixed, moving), covered))| Level {
            fixed,
            moving,
            stride: if index == 0 { finest_stride } else { 1 },
            covered,
            mask_share: share,
        })
        .collect())
}

/// Runs the adaptive stage on `moving`; `pins` are the points held at zero added
/// displacement.
pub fn register<B: Backend>(
    backend: &B,
    moving: &Moving<B>,
    target: &DeviceImage<B>,
    pins: &[Vector3<f64>],
    options: &AdaptiveOptions,
    progress: &dyn Progress,
) -> Result<Adaptive> {
    crate::backend::check_grids(&moving.image.grid, &target.grid)?;
    crate::backend::check_grids(&moving.coverage.grid, &target.grid)?;
    options.check()?;
    let levels = levels(
        backend,
        moving,
        target,
        (options.levels, options.finest_stride),
    )?;
    let mut points = pinned_points(pins);
    let mut stages = Vec::new();
    let evaluations = std::cell::Cell::new(Evaluations::default());
    progress.begin("adaptive RBF", levels.len() * options.cell_levels.len());
    for (index, level) in levels.iter().enumerate().rev() {
        let step = lattice_steps(&level.fixed.grid, options, moving.prealigned);
        let lattice = Lattice::new(backend, &level.moving.grid, level.stride, step)?;
        let target_variance = variance(backend, &level.fixed)?;
        let weights = energy_weights(target_variance, index, moving.prealigned, options);
        // Once the moving image is aligned, its smooth brightness difference to the target is
        // bias, not anatomy (the gain module): match it at each level, measured through the warp
        // found so far. Aligned means from the start after the articulated initialisation;
        // without it, from the second level on (matched on the unaligned image at the coarsest
        // level, the gain absorbed anatomy: 10° paper phantom, 1.42 → 1.62 mm).
        let aligned = moving.prealigned || index + 1 < levels.len();
        let gained = match options.gain_scale_mm > 0.0 && aligned {
            true => Some(matched_gain(backend, level, &lattice, &points, options)?),
            false => None,
        };
        let run = LevelRun {
            backend,
            index,
            level,
            lattice: &lattice,
            moving: gained.as_ref().unwrap_or(&level.moving.data),
            options,
        };
        let evaluator = run.evaluator(target_variance, weights);
        // Points added but not yet optimised (a refinement that added too few to pay for it).
        let mut waiting = 0;
        for &wanted in &options.cell_levels {
            stages.extend(run.refine(
                wanted,
                &mut points,
                &mut waiting,
                &evaluator,
                &evaluations,
                progress,
            )?);
        }
    }
    let (coefficients, _) = solve(&points, options.smoothing)?;
    progress.end();
    Ok(Adaptive {
        points,
        coefficients,
        lattice: {
            // Nodes every `step` sampled voxels are every stride · step voxels of the grid.
            let (finest, stride) = (&levels[0], levels[0].stride);
            let step = lattice_steps(&finest.fixed.grid, options, moving.prealigned);
            (finest.moving.grid.clone(), step.map(|s| s * stride))
        },
        stages,
        evaluations: evaluations.get(),
    })
}

/// The control points the stage starts from: one at each pin, held at zero displacement.
fn pinned_points(pins: &[Vector3<f64>]) -> Vec<ControlPoint> {
    pins.iter()
        .map(|p| ControlPoint {
            position: (*p).into(),
            displacement: [0.0; 3],
            pinned: true,
            cells: 0,
        })
        .collect()
}

/// The moving image at `level` with its smooth gain to the target matched, measured through
/// the warp of `points` so far.
fn matched_gain<B: Backend>(
    backend: &B,
    level: &Level<B>,
    lattice: &Lattice<B>,
    points: &[ControlPoint],
    options: &AdaptiveOptions,
) -> Result<B::Buffer<f32>> {
    let warped = warp_moving(
        backend,
        points,
        options.smoothing,
        lattice,
        &level.moving.data,
    )?;
    gain(
        backend,
        &warped.image,
        &level.fixed,
        &level.moving,
        options.gain_scale_mm,
    )
}

/// The membrane's and the bending energy's weights at pyramid level `index`, scaled by the
/// target's variance there (`target_variance`) so they do not depend on the intensity scale
/// (LNCC's term is scaled by it too). The membrane charges
/// the whole warp R; after the initialisation R is the small correction, without it R carries
/// the whole joint motion, which it would resist (half phantom 10° without initialisation,
/// weight 10: 1.43 → 2.37 mm).
fn energy_weights(
    target_variance: f64,
    index: usize,
    prealigned: bool,
    options: &AdaptiveOptions,
) -> [f64; 2] {
    let membrane = match prealigned {
        true => options.membrane.at_level(index) * target_variance,
        false => 0.0,
    };
    [membrane, options.bending.at_level(index) * target_variance]
}

/// One pyramid level of the adaptive stage: its images, lattice and moving image (with its
/// gain when matched).
struct LevelRun<'a, B: Backend> {
    backend: &'a B,
    index: usize,
    level: &'a Level<B>,
    lattice: &'a Lattice<B>,
    moving: &'a B::Buffer<f32>,
    options: &'a AdaptiveOptions,
}

impl<'a, B: Backend> LevelRun<'a, B> {
    /// The level's cost as the optimiser sees it: its image term (SSD, or local correlation
    /// scaled by the target's variance `target_variance`) and the energies weighted by
    /// `weights`.
    fn evaluator(&self, target_variance: f64, weights: [f64; 2]) -> Evaluator<'a, B> {
        let grid = &self.level.fixed.grid;
        let lncc = (self.similarity() == Similarity::Lncc)
            .then(|| LnccCost::new(grid, self.options.lncc_radius, target_variance as f32));
        let images = self.level.images(self.moving);
        Evaluator::new(self.backend, self.lattice, images, lncc, grid, weights)
    }

    /// The image term at this level.
    fn similarity(&self) -> Similarity {
        self.options.similarity.at_level(self.index)
    }

    /// One refinement: points added where `wanted` cells per axis fit poorly, then every point
    /// optimised; what it did, or None when it optimised nothing. Fewer than
    /// [`FEWEST_TO_OPTIMISE`] new points (counting those `waiting` from the level's refinements
    /// before) wait for the next refinement, except at the level's last.
    fn refine(
        &self,
        wanted: usize,
        points: &mut Vec<ControlPoint>,
        waiting: &mut usize,
        evaluator: &Evaluator<B>,
        evaluations: &std::cell::Cell<Evaluations>,
        progress: &dyn Progress,
    ) -> Result<Option<StageReport>> {
        let cells = self.cells(wanted);
        let [x, y, z] = cells;
        let refinement = format!("level {}, {x}x{y}x{z} cells", self.index);
        let added = self.add_points(points, wanted, cells)?;
        *waiting += added;
        let last = Some(&wanted) == self.options.cell_levels.last();
        if *waiting == 0 || (*waiting < FEWEST_TO_OPTIMISE && !last) {
            progress.step(&match added {
                0 => format!("{refinement}: no new points"),
                _ => format!(
                    "{refinement}: +{added} points, left to a later refinement of the level"
                ),
            });
            return Ok(None);
        }
        let added = std::mem::take(waiting);
        let result = self.optimise(points, evaluator, evaluations)?;
        progress.step(&format!(
            "{refinement}: +{added} points ({} in all), cost {:.4} -> {:.4}",
            points.len(),
            result.start_cost,
            result.cost
        ));
        Ok(Some(StageReport {
            level: self.index,
            cells,
            added,
            similarity: self.similarity(),
            cost_before: result.start_cost,
            cost_after: result.cost,
            iterations: result.iterations,
        }))
    }

    /// `wanted` cells per axis, fewer where an axis has too few voxels: counted on the moving
    /// image's grid (a finest level measured on fewer voxels places its points as without),
    /// and at most one per measured voxel.
    fn cells(&self, wanted: usize) -> [usize; 3] {
        let (grid, measured) = (&self.level.moving.grid, self.level.fixed.grid.dims);
        let cells = cells_on(grid, wanted, self.options.min_cell_voxels);
        std::array::from_fn(|a| cells[a].min(measured[a]))
    }

    /// Adds a control point at the centre of each cell that fits poorly (every cell at the
    /// first refinement) and is not crowded by a point already there; returns how many.
    fn add_points(
        &self,
        points: &mut Vec<ControlPoint>,
        wanted: usize,
        cells: [usize; 3],
    ) -> Result<usize> {
        let options = self.options;
        let grid = &self.level.fixed.grid;
        let warped = warp_moving(
            self.backend,
            points,
            options.smoothing,
            self.lattice,
            self.moving,
        )?;
        let ssd = cell_costs(self.backend, self.level, &warped.image, cells)?;
        let means = ssd.mean();
        // Per voxel of the target mask, so that a mask does not dilute the mean and call poor
        // the cells that fit as well as the rest. (Voxels without source data still count, as
        // the threshold's defaults were measured with.)
        let overall = ssd.total() / (grid.len() as f64 * self.level.mask_share);
        let cell_size = (0..3)
            .map(|a| grid.dims[a] as f64 * grid.spacing()[a] / cells[a] as f64)
            .fold(f64::INFINITY, f64::min);
        let mut added = 0;
        for (k, mean) in means.iter().enumerate() {
            let c = [
                k % cells[0],
                (k / cells[0]) % cells[1],
                k / (cells[0] * cells[1]),
            ];
            let centre = cell_centre(&self.level.moving.grid, cells, c);
            let poor = *mean > options.threshold.at_level(self.index) * overall
                || wanted == options.cell_levels[0];
            let crowded = points
                .iter()
                .any(|p| (Vector3::from(p.position) - centre).norm() < 0.5 * cell_size);
            if poor && !crowded && ssd.count[k] > 0 {
                points.push(ControlPoint {
                    position: centre.into(),
                    displacement: warped.coef.eval(&warped.centres, &centre).into(),
                    pinned: false,
                    cells: wanted,
                });
                added += 1;
            }
        }
        Ok(added)
    }

    /// L-BFGS on the free points' displacements through `evaluator`, counting each
    /// evaluation's traffic in `evaluations`.
    fn optimise(
        &self,
        points: &mut [ControlPoint],
        evaluator: &Evaluator<B>,
        evaluations: &std::cell::Cell<Evaluations>,
    ) -> Result<crate::nonrigid::optim::Minimised> {
        let options = self.options;
        let centres: Vec<Vector3<f64>> = points.iter().map(|p| Vector3::from(p.position)).collect();
        let system = RbfSystem::new(centres.clone(), options.smoothing)?;
        let free: Vec<usize> = (0..points.len()).filter(|&i| !points[i].pinned).collect();
        let x0: Vec<f64> = free.iter().flat_map(|&i| points[i].displacement).collect();
        let cost_grad = |x: &[f64]| -> Result<(f64, Vec<f64>)> {
            let before = self.backend.traffic();
            let mut values = vec![Vector3::zeros(); points.len()];
            for (k, &i) in free.iter().enumerate() {
                values[i] = Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]);
            }
            let coef = system.coefficients(&values)?;
            let e = evaluator.evaluate(&coef, &centres)?;
            let df = system.value_gradient(&e.points, &e.affine)?;
            let mut counted = evaluations.get();
            counted.add(self.backend.traffic() - before);
            evaluations.set(counted);
            Ok((
                e.cost,
                free.iter()
                    .flat_map(|&i| [df[i].x, df[i].y, df[i].z])
                    .collect(),
            ))
        };
        let result = lbfgs(
            cost_grad,
            x0,
            options.iterations.at_level(self.index),
            options.tolerance.at_level(self.index),
        )?;
        for (k, &i) in free.iter().enumerate() {
            points[i].displacement = [result.x[3 * k], result.x[3 * k + 1], result.x[3 * k + 2]];
        }
        Ok(result)
    }
}

impl Adaptive {
    /// R on every voxel of the finest level's grid (3 values per voxel, where the backend
    /// computes), scaled by `scale`, through the lattice and interpolation the optimiser used
    /// there. Only the lattice passes the host, to be scaled.
    pub fn warp_field<B: Backend>(&self, backend: &B, scale: f64) -> Result<DeviceImage<B>> {
        let (grid, step) = &self.lattice;
        let lattice = Lattice::new(backend, grid, 1, *step)?;
        let centres: Vec<Vector3<f64>> = self
            .points
            .iter()
            .map(|p| Vector3::from(p.position))
            .collect();
        let warp = lattice.warp(backend, &self.coefficients, &centres)?;
        let values: Vec<f32> = backend
            .download_one(&warp.values)?
            .iter()
            .map(|v| v * scale as f32)
            .collect();
        let values = backend.upload("scaled warp lattice", values)?;
        let params = RbfGradParams::new(grid, lattice.dims, lattice.step);
        Ok(DeviceImage {
            data: backend.warp_field(&params, &values)?,
            grid: grid.clone(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Affine;

    #[test]
    fn after_the_initialisation_the_lattice_is_half_a_cell_where_cells_are_wide() {
        let grid = |dims, h: [f64; 3]| {
            let mut a = Affine::identity();
            for k in 0..3 {
                a[(k, k)] = h[k];
            }
            Grid::new(dims, a).unwrap()
        };
        let options = AdaptiveOptions::default();
        // The half phantom: 16 cells of 10.6 × 20 × 19 mm; 5 mm is 2 voxels.
        let phantom = grid([68, 128, 128], [2.5, 2.5, 2.4]);
        assert_eq!(lattice_steps(&phantom, &options, true), [2, 4, 4]);
        // Without the initialisation, lattice_mm along every axis.
        assert_eq!(lattice_steps(&phantom, &options, false), [2, 2, 2]);
        // The knee at 2 mm: cells of 10 × 10 × 7.4 mm, no wider than two lattice spacings.
        let knee = grid([80, 80, 59], [2.0; 3]);
        assert_eq!(lattice_steps(&knee, &options, true), [3, 3, 3]);
        // A level too small for 16 cells: 5 × 10 × 10 cells of 3.4 × 3.2 × 3.2 voxels, half a
        // cell 1.7 and 1.6 voxels, rounded to 2.
        let coarse = grid([17, 32, 32], [10.0, 10.0, 9.6]);
        assert_eq!(lattice_steps(&coarse, &options, true), [2, 2, 2]);
    }
}
