//! A registration's settings as a whole: each stage's own (`[init]`, `[adaptive]`, `[dense]`,
//! beside their stages) and those of the pipeline that joins them, checked together.

use crate::check::{check_ranges, Range};
use crate::error::Result;
use crate::init::articulated::InitOptions;
use crate::nonrigid::adaptive::AdaptiveOptions;
use crate::nonrigid::dense::DenseOptions;

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
    /// The dense refinement after it.
    pub dense: DenseOptions,
    /// Control points held at zero added displacement on each bone's surface.
    pub pins_per_bone: usize,
    /// The adaptive warp is zero on the bones, which move exactly by their rigid motions, and
    /// rises linearly to its whole this far (mm) from the nearest bone; 0 leaves the warp on
    /// the bones as well. Measured (BENCHMARKS.md, 2026-12-03): 8 mm halves the bones' field
    /// error at 90° and lowers the body's on every pair; 2–4 mm (a step at the bone's surface
    /// at 2 mm voxels) leave a fold the unfolding cannot lift. Where two bones press on each
    /// other (1 mm, 90°) a few more tissue voxels between them stay folded.
    pub bone_margin_mm: f64,
}

impl Default for RegisterOptions {
    fn default() -> Self {
        RegisterOptions {
            initialise: true,
            init: InitOptions::default(),
            adaptive: AdaptiveOptions::default(),
            dense: DenseOptions::default(),
            pins_per_bone: 8,
            bone_margin_mm: 8.0,
        }
    }
}

impl crate::io::config::Settings for RegisterOptions {
    fn check(&self) -> Result<()> {
        RegisterOptions::check(self)
    }
}

impl RegisterOptions {
    /// The settings as the stages ran them: per-level values written out for their levels.
    pub fn as_run(&self) -> Self {
        RegisterOptions {
            adaptive: self.adaptive.as_run(),
            dense: self.dense.as_run(),
            ..self.clone()
        }
    }

    /// Rejects settings the registration cannot run with, naming the setting.
    pub fn check(&self) -> Result<()> {
        self.init.check()?;
        self.adaptive.check()?;
        self.dense.check()?;
        // Each pin is a control point of the dense RBF system: thousands would stall it.
        let (r, one) = (Range::new, |v: f64| vec![v]);
        #[rustfmt::skip]
        let table = [
            r("pins_per_bone", one(self.pins_per_bone as f64), (0.0, MAX_PINS_PER_BONE as f64), ""),
            r("bone_margin_mm", one(self.bone_margin_mm), (0.0, MAX_BONE_MARGIN_MM), " (mm)"),
        ];
        check_ranges("", &table)
    }
}

/// Most pins a bone may get (`pins_per_bone`).
const MAX_PINS_PER_BONE: usize = 64;

/// Widest margin over which the warp may rise from the bones (`bone_margin_mm`): beyond a few
/// centimetres it would hold most of the soft tissue still.
const MAX_BONE_MARGIN_MM: f64 = 50.0;
