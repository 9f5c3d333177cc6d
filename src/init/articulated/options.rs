//! The initialisation's settings (`[init]`): defaults, the range table and the checks that are
//! not ranges.

use crate::abi::Blending;
use crate::check::{check_ranges, Range};
use crate::error::{Error, Result};
use crate::joints::chain::{self, Link};
use crate::joints::confidence::FollowRules;
use crate::labels as label;
use crate::levels::MAX_LEVELS;
use crate::volume::Labels;

/// Most reach limits `init.reach` may list: each costs a coarse blend.
pub const MAX_REACH_CANDIDATES: usize = 6;

/// Name of a bone label code.
pub fn bone_name(code: u16) -> String {
    label::BONES
        .iter()
        .find(|(c, _)| *c == code)
        .map_or_else(|| format!("bone{code}"), |(_, name)| name.to_string())
}

/// Settings of the initialisation.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct InitOptions {
    /// Bone labels to register (default: every bone of the chain present).
    pub bones: Vec<u16>,
    /// The bones' tree: each bone's parent, rotation search and plausible range
    /// (crate::joints::chain; the knee's by default).
    pub chain: Vec<Link>,
    /// When a bone with weak evidence follows its parent (crate::joints::confidence).
    pub follow: FollowRules,
    /// Pyramid levels.
    pub levels: usize,
    /// Rigid registration runs on levels whose finest spacing is at least this (mm). At 1 mm
    /// the real knee's 0.625 mm scan was registered at 1.25 mm in-plane and 3 mm through-plane,
    /// where the bone's boundary voxels blend in the tissue around it; at 0.5 mm it uses the
    /// scan itself.
    pub finest_spacing_mm: f64,
    /// The bone region is the label dilated by this much (mm) and by `dilation_voxels`. A
    /// wide margin takes in tissue that does not move with the bone, and then the cost's
    /// minimum is not the bone's motion (real knee bent 10°, patella with a 3 mm margin: mean
    /// squared residual 183 600 at the true motion, 129 000 at the registered one, 0.74 mm
    /// off; without the margin and at 0.5 mm, 0.14 mm off).
    pub dilation_mm: f64,
    /// …plus this many voxels of the finest rigid level (its finest spacing). One voxel takes
    /// in the bone's partly covered boundary voxels, where the edge that fixes its pose is: on
    /// independent knee pairs at 2 mm (scripts/make_pair.py, 20° and 45°) the worst bone went
    /// from 1.29° / 0.58 mm to 0.28° / 0.17 mm.
    pub dilation_voxels: f64,
    /// Tilts of the search axis away from the labels' flexion axis (degrees).
    pub search_tilt_degrees: f64,
    /// A bone's registration, and its rotation search, start on the coarsest rigid level where
    /// its region still holds this many voxels. A coarse level widens the basin a candidate must land in: the
    /// candidates turn about the axis found from the labels, a few mm from the joint's own,
    /// and a thin bone far from the axis (the patella, 40 mm in front of it) is then missed
    /// by more than its thickness. With 200 the patella's search failed from 75–90° of
    /// flexion on (half and small phantoms: it picked −26° where the patella turned 84°);
    /// with 50 every bone is within 0.53° and 0.32 mm from 15° to 120° on the half phantom
    /// and within 1.1° on the small one; on the independent knee pairs nothing changed.
    pub search_min_voxels: usize,
    /// The search refines its three best candidates that lie at least this far apart
    /// (degrees), one per basin of the cost: candidates closer than this refine into the same
    /// minimum. The half phantom bent 90° by the independent generator has two minima for the
    /// patella, at 74° and 130° of the search; the three best candidates 5° apart were all at
    /// 122°–138° and converged to one fit 41° off, while the one at 74° refines to 0.4° off
    /// and fits 2.8 times better. With 20 that pair's patella is found and no bone of the knee
    /// pairs or the project's phantom (30°–120°) moved by more than 0.03°.
    pub search_basin_degrees: f64,
    /// How the bone motions are blended across the soft tissue. Dual quaternions by default:
    /// on the half phantom they lowered the initial field's mean error from 6.7 to 6.0 mm at
    /// 60° and from 14.1 to 12.2 mm at 90°, with fewer folds, than the paper's linear blend.
    pub blending: Blending,
    /// Limits of how far a small segment's tissue reaches (skinning::reach_scale: 1 as far
    /// as its distance, 2 twice as far as a bone of the largest segment's size would): each
    /// is tried on a coarse grid, and the limit kept is where the initialised image's local
    /// correlation with the target peaks (crate::init::reach); one value fixes it. Rising. The
    /// right limit differs between the project's phantom (2) and the real knee bent by the
    /// independent generator (1).
    pub reach: Vec<f64>,
}

impl InitOptions {
    /// The bones registered: those `bones` names, or every bone of the chain present in
    /// `labels`.
    pub fn bones_in(&self, labels: &Labels) -> Vec<u16> {
        match self.bones.is_empty() {
            true => chain::present(&self.chain, labels),
            false => self.bones.clone(),
        }
    }

    /// The name the chain gives bone `code`.
    pub fn name_of(&self, code: u16) -> String {
        chain::link(&self.chain, code).map_or_else(|| bone_name(code), |l| l.name.clone())
    }

    /// Rejects settings the stage cannot run with, naming the setting.
    pub fn check(&self) -> Result<()> {
        let bad = |what: &str| Err(Error::InvalidInput(format!("init.{what}")));
        let (r, one) = (Range::new, |v: f64| vec![v]);
        #[rustfmt::skip]
        let table = [
            r("levels", one(self.levels as f64), (1.0, MAX_LEVELS as f64), ""),
            r("finest_spacing_mm", one(self.finest_spacing_mm), (0.01, 100.0), " (mm)"),
            r("dilation_mm", one(self.dilation_mm), (0.0, 50.0), " (mm)"),
            r("dilation_voxels", one(self.dilation_voxels), (0.0, 10.0), ""),
            r("search_tilt_degrees", one(self.search_tilt_degrees), (0.0, 90.0), ""),
            r("search_basin_degrees", one(self.search_basin_degrees), (0.0, 90.0), ""),
            r("search_min_voxels", one(self.search_min_voxels as f64), (10.0, 1e6), ""),
            r("reach", self.reach.clone(), (1.0, 4.0), ""),
        ];
        check_ranges("init", &table)?;
        chain::check(&self.chain)?;
        self.follow.check()?;
        if self.reach.is_empty()
            || self.reach.len() > MAX_REACH_CANDIDATES
            || !self.reach.windows(2).all(|w| w[0] < w[1])
        {
            return bad(&format!(
                "reach must list 1 to {MAX_REACH_CANDIDATES} rising limits, each 1 to 4"
            ));
        }
        if (1..self.bones.len()).any(|i| self.bones[..i].contains(&self.bones[i])) {
            return bad("bones must not name a bone twice");
        }
        if self.bones.contains(&0) || self.bones.contains(&1) {
            return bad(
                "bones must list bone label codes; 0 is outside the body and 1 soft tissue",
            );
        }
        Ok(())
    }
}

impl Default for InitOptions {
    fn default() -> Self {
        InitOptions {
            bones: Vec::new(),
            chain: chain::knee(),
            follow: FollowRules::default(),
            levels: 4,
            finest_spacing_mm: 0.5,
            dilation_mm: 0.0,
            dilation_voxels: 1.0,
            search_tilt_degrees: 15.0,
            search_min_voxels: 50,
            search_basin_degrees: 20.0,
            blending: Blending::DualQuaternion,
            reach: vec![1.0, 1.5, 2.0],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reach_limits_must_rise() {
        for reach in [vec![1.5, 1.0], vec![1.0, 1.0], vec![]] {
            let options = InitOptions {
                reach: reach.clone(),
                ..Default::default()
            };
            let err = options.check().err().map(|e| e.to_string());
            assert!(
                err.as_deref().is_some_and(|e| e.contains("rising limits")),
                "{reach:?}: {err:?}"
            );
        }
    }
}
