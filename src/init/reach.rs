//! How far a small moving segment's soft tissue reaches (skinning::reach_scale), chosen per
//! pair: each candidate limit's initial field is made on a coarse grid, the source is seen
//! through it, and the limit where its image's correlation with the target (local, LNCC,
//! crate::images::similarity) peaks is kept.
//!
//! Why by the images: the right reach depends on the anatomy and the scan (on the project's
//! phantom the anterior thigh stays with the femur while the patella turns, on the real knee
//! bent by the independent generator the tissue follows the nearest bone), and the two truths
//! ask for different limits (BENCHMARKS.md). On both, the initialised image's LNCC ranked the
//! limits as the true field error did; its SSD did not (coil shading and noise differ between
//! the scans).

use crate::abi::{Interpolation, ResampleParams};
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use crate::images::pyramid;
use crate::images::similarity::local_correlation;
use crate::volume::Grid;

/// Spacing (mm) the candidates are compared at: the tissue at stake spans centimetres, and a
/// coarse grid makes each candidate cost a few percent of the full-resolution blend.
pub const JUDGE_SPACING_MM: f64 = 4.0;
/// Window radius (voxels of the coarse grid) of the local correlation: 5³ voxels, 2 cm.
pub const JUDGE_RADIUS: usize = 2;

/// One candidate limit and how well its initial field fits.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ReachTried {
    /// The reach limit.
    pub limit: f64,
    /// The mean local correlation ρ² of the source seen through its field with the target.
    pub local_correlation: f64,
}

/// The limit kept and every candidate's fit (none when only one limit was given).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ReachChoice {
    /// The reach limit the initial field was made with.
    pub limit: f64,
    /// The candidates, in the order tried.
    pub tried: Vec<ReachTried>,
}

/// The source and the target a candidate's field is judged on; brought down to
/// [`JUDGE_SPACING_MM`] only when there are candidates to compare ([`choose`]).
pub struct Judge<B: Backend> {
    source: DeviceImage<B>,
    target: DeviceImage<B>,
}

impl<B: Backend> Judge<B> {
    /// Judges against `source` and `target` (shared, not copied).
    pub fn new(source: &DeviceImage<B>, target: &DeviceImage<B>) -> Self {
        Judge {
            source: source.clone(),
            target: target.clone(),
        }
    }

    /// Both images smoothed and halved down to the judging spacing.
    fn coarse(&self, backend: &B) -> Result<Judge<B>> {
        Ok(Judge {
            source: pyramid::down_to_spacing(backend, self.source.clone(), JUDGE_SPACING_MM)?,
            target: pyramid::down_to_spacing(backend, self.target.clone(), JUDGE_SPACING_MM)?,
        })
    }

    /// The grid a candidate's field must be on: the target's.
    fn grid(&self) -> &Grid {
        &self.target.grid
    }

    /// The local correlation with the target of the source seen through `field` (the
    /// target's grid point → source point).
    fn score(&self, backend: &B, field: &DeviceImage<B>) -> Result<f64> {
        let params = ResampleParams::new(
            &self.source.grid,
            &self.target.grid,
            0.0,
            Interpolation::Linear,
        );
        let seen = DeviceImage {
            data: backend.resample(&params, &self.source.data, &field.data)?,
            grid: self.target.grid.clone(),
        };
        local_correlation(backend, &self.target, &seen, JUDGE_RADIUS)
    }
}

/// The reach at the peak of the fit: each limit among `limits` (rising) has its field
/// (`field_on(limit, grid)`: the grid's point → source point) scored on the `judge`'s images
/// brought down to [`JUDGE_SPACING_MM`], and the limit kept is the peak of the parabola through
/// the best one and its two neighbours (the first or last three where it is first or last;
/// [`peak`]). One limit is kept untried (and nothing is brought down); of two, the better.
///
/// Why a peak and not the best limit: two limits often fit almost equally (the half phantom at
/// 60°: 0.3484 and 0.3477), and which of them wins then turns on rounding and on the
/// inversion's last steps, while the registration's result differs by a tenth of a millimetre
/// between them; the peak moves little when the scores move little.
pub fn choose<B: Backend>(
    backend: &B,
    limits: &[f64],
    judge: &Judge<B>,
    field_on: impl Fn(f64, &Grid) -> Result<DeviceImage<B>>,
) -> Result<ReachChoice> {
    if let [only] = limits {
        return Ok(ReachChoice {
            limit: *only,
            tried: Vec::new(),
        });
    }
    let coarse = judge.coarse(backend)?;
    let mut tried = Vec::with_capacity(limits.len());
    for &limit in limits {
        let field = field_on(limit, coarse.grid())?;
        let local_correlation = coarse.score(backend, &field)?;
        tried.push(ReachTried {
            limit,
            local_correlation,
        });
    }
    let best = best_of(&tried);
    let limit = match tried.len() {
        0..=2 => tried[best].limit,
        n => peak(&tried[best.saturating_sub(1).min(n - 3)..][..3]),
    };
    Ok(ReachChoice { limit, tried })
}

/// The index of the best fit among `tried`, the first of equals; a NaN fit is never best
/// unless every fit is NaN.
fn best_of(tried: &[ReachTried]) -> usize {
    (1..tried.len()).fold(0, |best, i| {
        let (this, kept) = (tried[i].local_correlation, tried[best].local_correlation);
        match this > kept || (kept.is_nan() && !this.is_nan()) {
            true => i,
            false => best,
        }
    })
}

/// The limit at the vertex of the parabola through three candidates (rising limits), within
/// their limits; where the parabola is not concave (the fits fall ever slower or rise ever
/// faster, or lie on a line) the best one's limit. The vertex moves continuously with the fits
/// (not where the middle one fits worst and the outer two tie, which concave fits never do).
fn peak(three: &[ReachTried]) -> f64 {
    let [(x0, y0), (x1, y1), (x2, y2)] =
        [0, 1, 2].map(|i| (three[i].limit, three[i].local_correlation));
    let d0 = (y1 - y0) / (x1 - x0);
    let d1 = (y2 - y1) / (x2 - x1);
    let curvature = (d1 - d0) / (x2 - x0);
    if curvature.is_nan() || curvature >= 0.0 {
        return three[best_of(three)].limit;
    }
    // The parabola's slope d0 + curvature (2x − x0 − x1) vanishes at its vertex.
    // max/min rather than clamp: no panic should limits ever arrive unordered.
    (0.5 * (x0 + x1 - d0 / curvature)).max(x0).min(x2)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tried(points: [(f64, f64); 3]) -> Vec<ReachTried> {
        points
            .iter()
            .map(|&(limit, local_correlation)| ReachTried {
                limit,
                local_correlation,
            })
            .collect()
    }

    #[test]
    fn the_peak_is_the_vertex_of_the_parabola_through_three_fits() {
        // 0.5 − (x − 1.7)² at 1, 1.5 and 2.5 (uneven spacing).
        let fit = |x: f64| 0.5 - (x - 1.7) * (x - 1.7);
        let three = tried([1.0, 1.5, 2.5].map(|x| (x, fit(x))));
        assert!((peak(&three) - 1.7).abs() < 1e-12, "{}", peak(&three));
    }

    #[test]
    fn the_peak_moves_little_when_two_limits_fit_almost_alike() {
        // The half phantom at 60° (0.3484 and 0.3477), and the same with the tie reversed.
        let a = peak(&tried([(1.0, 0.3210), (1.5, 0.3484), (2.0, 0.3477)]));
        let b = peak(&tried([(1.0, 0.3210), (1.5, 0.3477), (2.0, 0.3484)]));
        assert!((a - 1.737).abs() < 1e-3, "{a}");
        assert!((b - 1.763).abs() < 1e-3, "{b}");
    }

    #[test]
    fn convex_fits_keep_the_best_limit() {
        // The real knee bent by the generator: the fit falls with the limit, ever slower.
        assert_eq!(
            peak(&tried([(1.0, 0.840), (1.5, 0.802), (2.0, 0.782)])),
            1.0
        );
        assert_eq!(peak(&tried([(1.0, 0.30), (1.5, 0.31), (2.0, 0.40)])), 2.0);
    }

    #[test]
    fn three_equal_fits_keep_the_first_limit() {
        assert_eq!(peak(&tried([(1.0, 0.3), (1.5, 0.3), (2.0, 0.3)])), 1.0);
    }
}
