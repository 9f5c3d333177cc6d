//! The dense refinement's settings (`[dense]` in a config file), their defaults and the
//! ranges they are checked against.

use crate::abi::dense::MAX_GAUSS_SIGMA;
use crate::check::{check_ranges, Range};
use crate::error::{Error, Result};
use crate::images::similarity::Similarity;
use crate::levels::PerLevel;

/// Settings of the dense refinement (`[dense]` in a config file).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DenseOptions {
    /// Run the stage (`--no-dense` skips it, `--dense` runs it whatever a settings file says).
    pub enabled: bool,
    /// Pyramid levels of the target it runs on, counted from the finest: 1 the target's own
    /// grid only, 2 a level at half the resolution first, and so on. Three by default: the
    /// coarse levels carry the tissue further, which the large bends whose truth keeps tissue
    /// volume need (2 mm 90°: 9.38 mm on the finest level alone, 4.25 on three), and where
    /// the image does not follow them (the phantom's smooth tissue) they keep their start
    /// (half phantom at 60°: 0.76 mm either way; BENCHMARKS.md, thirty-sixth session). The
    /// per-level defaults below read from the finest level up for any count: `levels = 1`
    /// alone runs the finest of the three, a fourth level repeats the coarsest.
    pub levels: usize,
    /// Iterations per level, coarse to fine.
    pub iterations: PerLevel<usize>,
    /// The image term per level, coarse to fine.
    pub similarity: PerLevel<Similarity>,
    /// Radius (voxels) of LNCC's windows per level, (2 r + 1)³ voxels.
    pub lncc_radius: PerLevel<usize>,
    /// σ (voxels) of the Gaussian smoothing each update gets (fluid), per level.
    pub fluid_sigma: PerLevel<f64>,
    /// σ (voxels) of the Gaussian smoothing the velocity gets every iteration (elastic), per
    /// level.
    pub elastic_sigma: PerLevel<f64>,
    /// The largest distance (mm) one update moves a voxel at the finest level; each coarser level's
    /// step is as much larger as its voxels. In mm, not voxels, because the knee pairs at 1 and 2
    /// mm both want about 2 mm (measured on three levels): a voxel's step at 1 mm left
    /// the volume-keeping pairs far behind (45° 2.26 against 1.44 mm, 90° 5.14 against 4.49), two
    /// voxels at 2 mm overshot (45° 1.98 against 2.51; BENCHMARKS.md, thirty-third session).
    pub step_mm: f64,
    /// The velocity is zero on the bones and on the voxels touching them and rises to its whole
    /// this far (mm) beyond; 0 leaves it on the bones too.
    pub bone_margin_mm: f64,
    /// Weight of the volume term, (log det J)² of the whole map per voxel, beside the image
    /// term, per level: real soft tissue keeps its volume, and the image alone does not say
    /// where tissue squeezed by the blend behind a bent knee went. It steers the steps; what a
    /// level keeps is decided by the image term alone. 0.3 against none, soft-tissue error on
    /// the 2 mm knee pairs bent 20° / 45° / 90° by make_pair.py: volume-keeping truths 1.44 /
    /// 3.19 / 6.74 → 1.24 / 2.43 / 5.16 mm, polyrigid truths (which squeeze the tissue behind
    /// the knee) 0.40 / 0.77 / 1.66 → 0.38 / 0.93 / 2.02 mm, the half phantom at 30° 0.61 →
    /// 0.58 mm; 0.5 and 1 gain more on the first and lose more on the others (BENCHMARKS.md,
    /// thirty-second session). The coarse levels' weight is what carries the 90° volume-keeping
    /// pair (kept on the sum of both terms, before the image rule: 0x0x0.3 6.73 mm, 0.3x0.3x0
    /// 5.49, 0.3 at every level 5.26; thirty-sixth session). One value, or one per level.
    /// 0 leaves it out.
    pub volume_weight: PerLevel<f64>,
    /// Each update is this share of the previous update plus the rest of this iteration's smoothed
    /// force (an exponential average of the updates before their scaling to the step; 0 takes the
    /// force alone), per level. With the step normalised to `step_mm`, the force alone flips at the
    /// voxels it moves furthest, so that the cost goes up and down every other iteration and a
    /// level stalls; averaging cancels the flip and keeps the steady part. On three levels,
    /// `0.5x0.5x0.25` against none (both with `min_gain` 0.003), soft-tissue error on
    /// the 2 mm knee pairs bent 20° / 45° / 90°: volume-keeping 1.24 / 2.43 / 5.16 → 1.32 / 1.98 /
    /// 4.46 mm, polyrigid 0.38 / 0.93 / 2.02 → 0.40 / 0.88 / 1.95; 0.5 on the finest level too
    /// gains more on the first (4.47 mm at 90°, 1.82 at 45°) and fits the 20° polyrigid pair's
    /// noise (0.50 mm, worse than no refinement; BENCHMARKS.md, thirty-third session).
    pub momentum: PerLevel<f64>,
    /// A level keeps an iteration's velocity only when its image term's cost is more than this
    /// fraction below the best so far, and stops after five iterations without one: smaller gains
    /// fit the scan's noise more than its anatomy, and stopping on them is where two
    /// backends' last-bit differences part ways.
    pub min_gain: f64,
}

impl Default for DenseOptions {
    fn default() -> Self {
        DenseOptions {
            enabled: true,
            levels: 3,
            iterations: coarse_to_fine(vec![100, 60, 30]),
            similarity: PerLevel::all(Similarity::Lncc),
            lncc_radius: PerLevel::all(2),
            fluid_sigma: coarse_to_fine(vec![3.0, 3.0, 2.0]),
            elastic_sigma: PerLevel::all(0.75),
            step_mm: 2.0,
            bone_margin_mm: 4.0,
            volume_weight: PerLevel::all(0.3),
            momentum: coarse_to_fine(vec![0.5, 0.5, 0.25]),
            min_gain: 0.003,
        }
    }
}

/// Per-level values, coarse to fine (at least one).
fn coarse_to_fine<T: Copy>(values: Vec<T>) -> PerLevel<T> {
    PerLevel::coarse_to_fine(values).expect("values are given")
}

/// Most levels the stage runs on.
const MAX_DENSE_LEVELS: usize = 4;
/// Most iterations at one level.
const MAX_ITERATIONS: usize = 1000;
/// Widest LNCC window radius (voxels).
const MAX_LNCC_RADIUS: usize = 8;
/// Widest margin (mm) over which the velocity may rise from the bones.
const MAX_BONE_MARGIN_MM: f64 = 50.0;
/// Largest step (mm) of one update at the finest level.
const MAX_STEP_MM: f64 = 20.0;
/// Largest weight of the volume term.
const MAX_VOLUME_WEIGHT: f64 = 100.0;
/// Largest share of the previous update an update keeps (below 1: the force still counts).
const MAX_MOMENTUM: f64 = 0.95;
/// Largest gain a level may ask of an iteration.
const MAX_MIN_GAIN: f64 = 0.5;

impl DenseOptions {
    /// The settings with each per-level value written out for the levels run (the defaults'
    /// three values read for another count), as the report records them.
    pub fn as_run(&self) -> Self {
        let n = self.levels;
        DenseOptions {
            iterations: self.iterations.for_levels(n),
            similarity: self.similarity.for_levels(n),
            lncc_radius: self.lncc_radius.for_levels(n),
            fluid_sigma: self.fluid_sigma.for_levels(n),
            elastic_sigma: self.elastic_sigma.for_levels(n),
            volume_weight: self.volume_weight.for_levels(n),
            momentum: self.momentum.for_levels(n),
            ..self.clone()
        }
    }

    /// Rejects settings the stage cannot run with, naming the setting.
    pub fn check(&self) -> Result<()> {
        let counts = |v: &PerLevel<usize>| v.values().iter().map(|&n| n as f64).collect();
        let voxels = " (voxels)";
        let (r, one) = (Range::new, |v: f64| vec![v]);
        #[rustfmt::skip]
        let table = [
            r("levels", one(self.levels as f64), (1.0, MAX_DENSE_LEVELS as f64), ""),
            r("iterations", counts(&self.iterations), (0.0, MAX_ITERATIONS as f64), ""),
            r("lncc_radius", counts(&self.lncc_radius), (1.0, MAX_LNCC_RADIUS as f64), voxels),
            r("fluid_sigma", self.fluid_sigma.values().to_vec(), (0.0, MAX_GAUSS_SIGMA), voxels),
            r("elastic_sigma", self.elastic_sigma.values().to_vec(), (0.0, MAX_GAUSS_SIGMA), voxels),
            r("step_mm", one(self.step_mm), (0.01, MAX_STEP_MM), " (mm)"),
            r("bone_margin_mm", one(self.bone_margin_mm), (0.0, MAX_BONE_MARGIN_MM), " (mm)"),
            r("volume_weight", self.volume_weight.values().to_vec(), (0.0, MAX_VOLUME_WEIGHT), ""),
            r("momentum", self.momentum.values().to_vec(), (0.0, MAX_MOMENTUM), ""),
            r("min_gain", one(self.min_gain), (0.0, MAX_MIN_GAIN), ""),
        ];
        check_ranges("dense", &table)?;
        let (n, d) = (self.levels, DenseOptions::default());
        // The defaults' per-level values read for any level count (`levels = 1` alone runs
        // the finest level's 30 iterations, fluid σ 2, momentum 0.25); each value a file gives
        // that does not fit the count is named, all in one message.
        let counts = [
            self.iterations
                .check_given(&d.iterations, "dense.iterations", n),
            self.similarity
                .check_given(&d.similarity, "dense.similarity", n),
            self.lncc_radius
                .check_given(&d.lncc_radius, "dense.lncc_radius", n),
            self.fluid_sigma
                .check_given(&d.fluid_sigma, "dense.fluid_sigma", n),
            self.elastic_sigma
                .check_given(&d.elastic_sigma, "dense.elastic_sigma", n),
            self.momentum.check_given(&d.momentum, "dense.momentum", n),
            self.volume_weight
                .check_given(&d.volume_weight, "dense.volume_weight", n),
        ];
        let wrong: Vec<String> = counts
            .into_iter()
            .filter_map(|c| c.err().map(|e| e.to_string()))
            .collect();
        match wrong.is_empty() {
            true => Ok(()),
            false => Err(Error::InvalidInput(wrong.join("; "))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_defaults_fit_any_level_count() {
        for levels in 1..=MAX_DENSE_LEVELS {
            let options = DenseOptions {
                levels,
                ..Default::default()
            };
            assert!(options.check().is_ok(), "{levels} levels");
        }
    }

    #[test]
    fn the_defaults_pass_their_own_checks_and_bad_values_are_named() {
        assert!(DenseOptions::default().check().is_ok());
        let bad = DenseOptions {
            step_mm: 0.0,
            ..Default::default()
        };
        let err = bad.check().unwrap_err().to_string();
        assert!(err.contains("dense.step_mm"), "{err}");
        let bad = DenseOptions {
            fluid_sigma: PerLevel::all(50.0),
            ..Default::default()
        };
        assert!(bad
            .check()
            .unwrap_err()
            .to_string()
            .contains("dense.fluid_sigma"));
        let bad = DenseOptions {
            momentum: PerLevel::all(1.0),
            ..Default::default()
        };
        let err = bad.check().unwrap_err().to_string();
        assert!(err.contains("dense.momentum"), "{err}");
        let bad = DenseOptions {
            min_gain: 0.6,
            ..Default::default()
        };
        let err = bad.check().unwrap_err().to_string();
        assert!(err.contains("dense.min_gain"), "{err}");
        // Values given for three levels where two levels run: each such setting named at once.
        let bad = DenseOptions {
            levels: 2,
            iterations: "50x40x20".parse().unwrap(),
            momentum: "0.5x0.4x0.2".parse().unwrap(),
            ..Default::default()
        };
        let err = bad.check().unwrap_err().to_string();
        for name in ["iterations", "momentum"] {
            assert!(err.contains(&format!("dense.{name} has 3 values")), "{err}");
        }
        assert!(err.contains("2 pyramid levels"), "{err}");
        assert!(
            !err.contains("fluid_sigma"),
            "a default is not named: {err}"
        );
        let bad = DenseOptions {
            volume_weight: "0x0.3".parse().unwrap(),
            ..Default::default()
        };
        let err = bad.check().unwrap_err().to_string();
        assert!(err.contains("dense.volume_weight"), "{err}");
    }
}
