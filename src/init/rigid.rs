//! Per-bone rigid registration by sum of squared intensity differences (paper eq. 2):
//! Levenberg-Marquardt on 6 parameters, normal equations reduced per column by the rigid_gn
//! kernel and added on the device in f64, coarse to fine; large poses start from a one-pass
//! score of hundreds of rotations about the joint (rigid_score kernel).

use crate::abi::{pack_candidates, RigidParams, ScoreParams, RIGID_SUMS as SUMS, SCORE_SUMS};
use crate::backend::{check_grids, Backend, BoneImages, DeviceImage};
use crate::error::{Error, Result};
use crate::volume::Affine;
use nalgebra::{Matrix6, Rotation3, Vector3, Vector6};

/// The folded Gauss-Newton system at one motion.
#[derive(Clone, Debug)]
pub struct NormalEquations {
    /// JᵀJ.
    pub jtj: Matrix6<f64>,
    /// Jᵀr.
    pub jtr: Vector6<f64>,
    /// Σ r².
    pub ssd: f64,
    /// Voxels that contributed.
    pub count: f64,
}

/// A bone's images at one pyramid level, where the backend computes.
pub struct BoneLevel<'a, B: Backend> {
    /// The source S.
    pub source: &'a DeviceImage<B>,
    /// The bone's region (≥ 0.5 inside), on the source's grid.
    pub mask: &'a DeviceImage<B>,
    /// The target T.
    pub target: &'a DeviceImage<B>,
}

impl<B: Backend> BoneLevel<'_, B> {
    fn images(&self) -> BoneImages<'_, B::Buffer<f32>> {
        BoneImages {
            source: &self.source.data,
            mask: &self.mask.data,
            target: &self.target.data,
        }
    }
}

/// The Gauss-Newton system of `level` at `motion`, linearised about `centre`: the rigid_gn
/// kernel's column sums added on the device (f64); 29 numbers come back.
pub fn normal_equations<B: Backend>(
    backend: &B,
    level: &BoneLevel<B>,
    motion: &Affine,
    centre: &Vector3<f64>,
) -> Result<NormalEquations> {
    check_grids(&level.source.grid, &level.mask.grid)?;
    let params = RigidParams::new(
        &level.source.grid,
        &level.target.grid,
        motion,
        (*centre).into(),
    );
    let partial = backend.rigid_sums(&params, &level.images())?;
    let sums = backend.download_one(&backend.sum_partials(&partial, SUMS)?)?;
    let mut jtj = Matrix6::zeros();
    let mut k = 0;
    for a in 0..6 {
        for b in a..6 {
            jtj[(a, b)] = sums[k];
            jtj[(b, a)] = sums[k];
            k += 1;
        }
    }
    Ok(NormalEquations {
        jtj,
        jtr: Vector6::from_fn(|a, _| sums[21 + a]),
        ssd: sums[27],
        count: sums[28],
    })
}

/// The small motion δ = (ω, v) about `centre`: y ↦ R(ω)(y − c) + c + v.
pub fn small_motion(delta: &Vector6<f64>, centre: &Vector3<f64>) -> Affine {
    let r = Rotation3::new(Vector3::new(delta[0], delta[1], delta[2]));
    let t = centre - r * centre + Vector3::new(delta[3], delta[4], delta[5]);
    let mut m = Affine::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(r.matrix());
    m.fixed_view_mut::<3, 1>(0, 3).copy_from(&t);
    m
}

/// Mean squared residual of each candidate; candidates that keep fewer than half of the best
/// covered candidate's voxels inside the target are scored infinite (they win by leaving).
pub fn score_candidates<B: Backend>(
    backend: &B,
    level: &BoneLevel<B>,
    candidates: &[Affine],
) -> Result<Vec<f64>> {
    let scores = score_covered(backend, level, candidates)?;
    let most = scores.iter().map(|s| s.voxels).fold(0.0, f64::max);
    Ok(scores
        .iter()
        .map(|s| match s.voxels > 0.0 && s.voxels >= 0.5 * most {
            true => s.cost,
            false => f64::INFINITY,
        })
        .collect())
}

/// How one motion of a bone fits the target.
#[derive(Clone, Copy, Debug)]
pub struct Score {
    /// Mean squared residual (infinite when no voxel lands inside the target).
    pub cost: f64,
    /// Voxels of the bone region that land inside the target.
    pub voxels: f64,
    /// Correlation of the bone region's intensities with the target's where they land: how
    /// much the moved bone looks like what the target holds there, whatever the two scans'
    /// gain and offset (0 when either is constant).
    pub correlation: f64,
}

impl Score {
    /// From the kernel's sums: Σr², count, ΣS, ΣT, ΣS², ΣT², ΣST.
    fn from_sums(s: &[f64]) -> Self {
        let n = s[1];
        if n <= 0.0 {
            return Score {
                cost: f64::INFINITY,
                voxels: 0.0,
                correlation: 0.0,
            };
        }
        let var_s = s[4] - s[2] * s[2] / n;
        let var_t = s[5] - s[3] * s[3] / n;
        let cov = s[6] - s[2] * s[3] / n;
        let spread = (var_s * var_t).sqrt();
        Score {
            cost: s[0] / n,
            voxels: n,
            correlation: if spread > 0.0 { cov / spread } else { 0.0 },
        }
    }
}

/// Each candidate's [`Score`].
pub fn score_covered<B: Backend>(
    backend: &B,
    level: &BoneLevel<B>,
    candidates: &[Affine],
) -> Result<Vec<Score>> {
    check_grids(&level.source.grid, &level.mask.grid)?;
    let params = ScoreParams::new(&level.source.grid, &level.target.grid, candidates.len());
    let packed = backend.upload("candidate motions", pack_candidates(candidates))?;
    let partial = backend.rigid_scores(&params, &level.images(), &packed)?;
    let sums = SCORE_SUMS * candidates.len();
    let totals = backend.download_one(&backend.sum_partials(&partial, sums)?)?;
    Ok(totals
        .chunks_exact(SCORE_SUMS)
        .map(Score::from_sums)
        .collect())
}

/// How a bone's refinement at one level went.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LevelReport {
    /// Iterations run.
    pub iterations: usize,
    /// Mean squared residual before.
    pub cost_before: f64,
    /// Mean squared residual after.
    pub cost_after: f64,
    /// Voxels of the bone region inside the target.
    pub voxels: f64,
}

/// Refinement settings.
#[derive(Clone, Debug)]
pub struct RefineOptions {
    /// Most LM iterations per level.
    pub max_iterations: usize,
    /// Stop when the step is below this rotation (rad) and translation (mm).
    pub tolerance: f64,
}

impl Default for RefineOptions {
    fn default() -> Self {
        RefineOptions {
            max_iterations: 40,
            tolerance: 1e-4,
        }
    }
}

/// Levenberg-Marquardt refinement of `motion` at one pyramid level. The system is linearised
/// about the moved centroid of the bone region, so rotation and translation are decoupled and
/// similarly scaled.
pub fn refine<B: Backend>(
    backend: &B,
    level: &BoneLevel<B>,
    motion: Affine,
    region_centroid: &Vector3<f64>,
    options: &RefineOptions,
) -> Result<(Affine, LevelReport)> {
    let mut m = motion;
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let centre_of = |m: &Affine| (m * region_centroid.push(1.0)).xyz();
    let mut centre = centre_of(&m);
    let mut eq = normal_equations(backend, level, &m, &centre)?;
    if eq.count < 10.0 {
        return Err(Error::InvalidInput(
            "the bone region falls outside the target: no overlap to register".into(),
        ));
    }
    let cost_before = eq.ssd / eq.count;
    let mut cost = cost_before;
    while iterations < options.max_iterations {
        iterations += 1;
        let mut a = eq.jtj;
        for k in 0..6 {
            a[(k, k)] += lambda * eq.jtj[(k, k)].max(1e-12);
        }
        let Some(delta) = a.cholesky().map(|c| -c.solve(&eq.jtr)) else {
            lambda *= 10.0;
            continue;
        };
        let trial = small_motion(&delta, &centre) * m;
        let trial_cost = score_candidates(backend, level, &[trial])?[0];
        if trial_cost < cost {
            m = trial;
            cost = trial_cost;
            lambda = (lambda / 3.0).max(1e-7);
            let step = delta.fixed_rows::<3>(0).norm() + delta.fixed_rows::<3>(3).norm() / 100.0;
            if step < options.tolerance {
                break;
            }
            centre = centre_of(&m);
            eq = normal_equations(backend, level, &m, &centre)?;
        } else {
            lambda *= 4.0;
            if lambda > 1e6 {
                break;
            }
        }
    }
    Ok((
        m,
        LevelReport {
            iterations,
            cost_before,
            cost_after: cost,
            voxels: eq.count,
        },
    ))
}
