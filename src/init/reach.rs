//! How far a small moving segment's soft tissue reaches (skinning::reach_scale), chosen per
//! pair: each candidate limit's initial field is made on a coarse grid, the source is seen
//! through it, and the limit whose image correlates best with the target locally (LNCC,
//! crate::images::similarity) is kept.
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

/// The limit among `limits` whose field (`field_on(limit, grid)`: the grid's point → source
/// point) scores highest on the `judge`'s images brought down to [`JUDGE_SPACING_MM`]; the
/// first of equals. One limit is kept untried (and nothing is brought down).
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
    let best = tried.iter().fold(&tried[0], |best, t| {
        if t.local_correlation > best.local_correlation {
            t
        } else {
            best
        }
    });
    Ok(ReachChoice {
        limit: best.limit,
        tried: tried.clone(),
    })
}
