//! The adaptive stage's settings (`[adaptive]`) and their checks: defaults, one range table,
//! and the checks that are not ranges.

use crate::check::{check_ranges, Range, UNBOUNDED};
use crate::error::{Error, Result};
use crate::images::similarity::Similarity;
use crate::levels::{PerLevel, MAX_LEVELS};

/// Most voxels the finest level may step between the ones it measures (finest_stride).
const MAX_STRIDE: usize = 4;
/// Default weight of the membrane energy (AdaptiveOptions::membrane).
const MEMBRANE_DEFAULT: f64 = 3.0;
/// Default weight of the bending energy (AdaptiveOptions::bending).
const BENDING_DEFAULT: f64 = 0.0;

/// Settings of the adaptive stage; every threshold is relative, so the defaults hold across
/// intensity scales.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AdaptiveOptions {
    /// Pyramid levels.
    pub levels: usize,
    /// Cells per axis at each refinement, coarse to fine.
    pub cell_levels: Vec<usize>,
    /// A cell keeps at least this many voxels per axis at the level it is used on.
    pub min_cell_voxels: usize,
    /// Cells whose mean squared residual exceeds this multiple of the mean over all cells get a
    /// control point (the 2³ cells always do). Measured on the phantom: raising it from 1 to 8
    /// cut the points from ~900 to ~180 and lowered the error (10°, small: 2.70 → 1.40 mm) —
    /// fewer, well-lattice points keep the optimisation well conditioned. At the finest level
    /// 4: with the bones held rigid and the lattice tied to the cells, every one of fifteen
    /// measured pairs came out as accurate or more at two decimals, the knee and the
    /// generator's pairs by 0.01–0.10 mm (knee 1 mm 90°: 1.89 → 1.79 mm; BENCHMARKS.md,
    /// fourteenth session). Per pyramid level, coarse to fine.
    pub threshold: PerLevel<f64>,
    /// L-BFGS iterations per refinement, per pyramid level, coarse to fine.
    pub iterations: PerLevel<usize>,
    /// Relative cost decrease below which an optimisation stops.
    pub tolerance: PerLevel<f64>,
    /// Finest spacing (mm) of the lattice the warp is evaluated on. After the initialisation,
    /// along an axis where half a level's finest cell is wider (cells wider than about two
    /// of these), the lattice is half a cell there ([`lattice_steps`]).
    pub lattice_mm: f64,
    /// Smoothing μ added to the RBF system's diagonal (0 interpolates).
    pub smoothing: f64,
    /// Weight of the warp's membrane energy (crate::nonrigid::regularise) in the cost, relative to the
    /// target's intensity variance at each level: a strain of ε everywhere costs as much as a
    /// residual of √membrane·ε standard deviations at every voxel.
    pub membrane: PerLevel<f64>,
    /// Weight of the warp's bending energy (crate::nonrigid::regularise, mm⁻²) in the cost, relative to
    /// the target's intensity variance at each level, in mm²: a curvature κ (mm⁻¹ per mm)
    /// everywhere costs as much as a residual of √bending·κ standard deviations at every voxel.
    /// Unlike the membrane it is applied with or without the initialisation: it leaves a limb
    /// turning as a whole free.
    pub bending: PerLevel<f64>,
    /// Scale (mm) of the smooth intensity gain matched between the moving and the target
    /// image before optimising (crate::nonrigid::gain); 0 leaves intensities as they are.
    pub gain_scale_mm: f64,
    /// The cost's image term per pyramid level, coarse to fine: SSD after the gain, or LNCC
    /// (where the cells that fit poorly are still found by their SSD). SSD by default: LNCC at
    /// the finest level ("ssdxssdxlncc") registers the generator's knee pairs, whose scans differ
    /// in bias and noise, better (body 0.46/1.05/2.25/1.06 → 0.42/0.95/2.20/0.95 mm at 2 mm
    /// 20°/45°/90° and 1 mm 45°; 2026-12-03, CPU) and survives a contrast change that SSD does
    /// not (tests/adaptive.rs), but it cost the project's phantom, whose poses share one
    /// intensity model, 0.02–0.09 mm, takes ~1.5× the time, and as a default it put the
    /// whole-pipeline backends 0.117 mm apart at 30° (SSD: 0.017; BENCHMARKS.md).
    pub similarity: PerLevel<Similarity>,
    /// Radius (voxels) of LNCC's windows: (2 r + 1)³ voxels.
    pub lncc_radius: usize,
    /// The finest level's image term is measured on every `finest_stride`-th voxel of the
    /// target per axis (the moving image still sampled at full resolution through the warp),
    /// as elastix samples: 2 takes an eighth of the voxels. 1 measures every voxel.
    pub finest_stride: usize,
}

/// The cell threshold's default: 8, and 4 at the finest level (AdaptiveOptions::threshold).
fn default_threshold() -> PerLevel<f64> {
    PerLevel::coarse_to_fine(vec![8.0, 8.0, 4.0]).expect("three values")
}

impl Default for AdaptiveOptions {
    fn default() -> Self {
        AdaptiveOptions {
            levels: 3,
            cell_levels: vec![2, 4, 8, 16],
            min_cell_voxels: 3,
            threshold: default_threshold(),
            iterations: PerLevel::all(30),
            tolerance: PerLevel::all(1e-5),
            lattice_mm: 5.0,
            smoothing: 0.0,
            membrane: PerLevel::all(MEMBRANE_DEFAULT),
            bending: PerLevel::all(BENDING_DEFAULT),
            gain_scale_mm: 20.0,
            similarity: PerLevel::all(Similarity::Ssd),
            lncc_radius: 2,
            finest_stride: 1,
        }
    }
}

impl AdaptiveOptions {
    /// The settings with each per-level value written out for the levels run (the default
    /// threshold read for another count), as the report records them.
    pub fn as_run(&self) -> Self {
        let n = self.levels;
        AdaptiveOptions {
            threshold: self.threshold.for_levels(n),
            iterations: self.iterations.for_levels(n),
            tolerance: self.tolerance.for_levels(n),
            membrane: self.membrane.for_levels(n),
            bending: self.bending.for_levels(n),
            similarity: self.similarity.for_levels(n),
            ..self.clone()
        }
    }

    /// Rejects settings the stage cannot run with, naming the setting.
    pub fn check(&self) -> Result<()> {
        let bad = |what: &str| Err(Error::InvalidInput(format!("adaptive.{what}")));
        let counts = |v: &[usize]| v.iter().map(|&n| n as f64).collect::<Vec<_>>();
        let many = UNBOUNDED;
        let (r, one) = (Range::new, |v: f64| vec![v]);
        #[rustfmt::skip]
        let table = [
            r("levels", one(self.levels as f64), (1.0, MAX_LEVELS as f64), ""),
            r("cell_levels", counts(&self.cell_levels), (1.0, MAX_CELLS as f64), " cells"),
            r("min_cell_voxels", one(self.min_cell_voxels as f64), (1.0, 64.0), ""),
            r("lattice_mm", one(self.lattice_mm), (1.0, 100.0), " (mm)"),
            r("smoothing", one(self.smoothing), (0.0, many), ""),
            r("gain_scale_mm", one(self.gain_scale_mm), (0.0, many), " (mm)"),
            r("lncc_radius", one(self.lncc_radius as f64), (1.0, MAX_LNCC_RADIUS as f64), " (voxels)"),
            r("finest_stride", one(self.finest_stride as f64), (1.0, MAX_STRIDE as f64), " (voxels)"),
            // Below 1 nearly every cell would get a point: the RBF system grows unbounded.
            r("threshold", self.threshold.values().to_vec(), (1.0, many), ""),
            r("tolerance", self.tolerance.values().to_vec(), (0.0, MAX_TOLERANCE), ""),
            r("membrane", self.membrane.values().to_vec(), (0.0, many), ""),
            r("bending", self.bending.values().to_vec(), (0.0, many), ""),
            r("iterations", counts(self.iterations.values()), (0.0, MAX_ITERATIONS as f64), ""),
        ];
        check_ranges("adaptive", &table)?;
        // Every cell of the first refinement gets a point (crate::nonrigid::adaptive): 16³ there
        // made thousands, and the dense RBF system stalled.
        let rising = self.cell_levels.windows(2).all(|w| w[0] < w[1]);
        let first = self.cell_levels.first();
        if !rising || first.is_none_or(|&c| c > MAX_FIRST_CELLS) {
            return bad(&format!(
                "cell_levels must rise coarse to fine and start at {MAX_FIRST_CELLS} cells or fewer"
            ));
        }
        if self.iterations.values().iter().all(|&i| i == 0) {
            return bad(
                "iterations must be above 0 at one level at least (0 everywhere would \
                        leave the warp untouched)",
            );
        }
        // The default reads as "4 at the finest level, 8 above" for any level count.
        let threshold = &self.threshold;
        threshold.check_given(&default_threshold(), "adaptive.threshold", self.levels)?;
        self.similarity.check("adaptive.similarity", self.levels)?;
        self.membrane.check("adaptive.membrane", self.levels)?;
        self.bending.check("adaptive.bending", self.levels)?;
        self.tolerance.check("adaptive.tolerance", self.levels)?;
        self.iterations.check("adaptive.iterations", self.levels)
    }
}

/// Largest relative cost decrease at which an optimisation may be told to stop (below 1).
const MAX_TOLERANCE: f64 = 0.5;
/// Most cells per axis at the first refinement, where every cell gets a point.
const MAX_FIRST_CELLS: usize = 4;
/// Most cells per axis at a refinement (64³ cells).
const MAX_CELLS: usize = 64;
/// Widest LNCC window radius (voxels): 17³ voxels a window.
const MAX_LNCC_RADIUS: usize = 8;
/// Most L-BFGS iterations per refinement.
const MAX_ITERATIONS: usize = 10_000;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_threshold_fits_any_level_count_and_a_given_one_its_own() {
        for levels in 1..=MAX_LEVELS {
            let options = AdaptiveOptions {
                levels,
                ..Default::default()
            };
            assert!(options.check().is_ok(), "{levels} levels");
        }
        let given = AdaptiveOptions {
            levels: 2,
            threshold: "8x8x3".parse().unwrap(),
            ..Default::default()
        };
        let err = given.check().unwrap_err().to_string();
        assert!(
            err.contains("adaptive.threshold"),
            "three values for two levels: {err}"
        );
    }
}
