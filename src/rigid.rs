//! Per-bone rigid registration by sum of squared intensity differences (paper eq. 2):
//! Levenberg-Marquardt on 6 parameters, normal equations reduced per column by the rigid_gn
//! kernel and folded here in f64, coarse to fine; large poses start from a one-pass score of
//! hundreds of rotations about the joint (rigid_score kernel).

use crate::abi::RIGID_SUMS as SUMS;
use crate::backend::Backend;
use crate::error::{Error, Result};
use crate::volume::{Affine, Volume};
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

/// Folds per-column sums (layout of shaders/rigid_gn.wgsl) in f64, in column order.
pub fn fold_normal_equations(partial: &[f32]) -> NormalEquations {
    let mut sums = [0.0f64; SUMS];
    for column in partial.chunks_exact(SUMS) {
        for (s, v) in sums.iter_mut().zip(column) {
            *s += *v as f64;
        }
    }
    let mut jtj = Matrix6::zeros();
    let mut k = 0;
    for a in 0..6 {
        for b in a..6 {
            jtj[(a, b)] = sums[k];
            jtj[(b, a)] = sums[k];
            k += 1;
        }
    }
    NormalEquations {
        jtj,
        jtr: Vector6::from_fn(|a, _| sums[21 + a]),
        ssd: sums[27],
        count: sums[28],
    }
}

/// Folds per-column candidate partials into (Σ r², count) per candidate, in f64.
pub fn fold_scores(partial: &[f32], candidates: usize) -> Vec<(f64, f64)> {
    let mut out = vec![(0.0, 0.0); candidates];
    for column in partial.chunks_exact(2 * candidates) {
        for (c, o) in out.iter_mut().enumerate() {
            o.0 += column[2 * c] as f64;
            o.1 += column[2 * c + 1] as f64;
        }
    }
    out
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
    source: &Volume,
    mask: &Volume,
    target: &Volume,
    candidates: &[Affine],
) -> Result<Vec<f64>> {
    let partial = backend.rigid_scores(source, mask, target, candidates)?;
    let folded = fold_scores(&partial, candidates.len());
    let most = folded.iter().map(|s| s.1).fold(0.0, f64::max);
    Ok(folded
        .iter()
        .map(|&(ssd, n)| {
            if n > 0.0 && n >= 0.5 * most {
                ssd / n
            } else {
                f64::INFINITY
            }
        })
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
    source: &Volume,
    mask: &Volume,
    target: &Volume,
    motion: Affine,
    region_centroid: &Vector3<f64>,
    options: &RefineOptions,
) -> Result<(Affine, LevelReport)> {
    let mut m = motion;
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let centre_of = |m: &Affine| (m * region_centroid.push(1.0)).xyz();
    let mut centre = centre_of(&m);
    let mut eq =
        fold_normal_equations(&backend.rigid_sums(source, mask, target, &m, centre.into())?);
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
        let trial_cost = score_candidates(backend, source, mask, target, &[trial])?[0];
        if trial_cost < cost {
            m = trial;
            cost = trial_cost;
            lambda = (lambda / 3.0).max(1e-7);
            let step = delta.fixed_rows::<3>(0).norm() + delta.fixed_rows::<3>(3).norm() / 100.0;
            if step < options.tolerance {
                break;
            }
            centre = centre_of(&m);
            eq = fold_normal_equations(&backend.rigid_sums(
                source,
                mask,
                target,
                &m,
                centre.into(),
            )?);
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
