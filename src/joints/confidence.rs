//! How far to trust a bone's rigid registration, and whether it follows its parent.
//!
//! A thin or small bone, or one the target sees only in part, has little evidence of its own:
//! its cost can have a wrong minimum lower than the true one (a fibula at ~1 mm voxels turned
//! 66° where its tibia turned 22°). Such a bone keeps its own motion only when that motion
//! lowers its cost clearly below the cost at its parent's motion. Any bone whose motion
//! relative to its parent lies beyond the chain's plausible range follows the parent. The
//! decision and the figures behind it are reported, with a warning when a motion is
//! implausible or weakly determined.

/// What decides whether a weak bone keeps its own motion.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FollowRules {
    /// A bone with fewer voxels than this at the finest rigid level is small.
    pub small_voxels: f64,
    /// A bone with less than this share of its voxels inside the target is barely seen.
    pub min_seen: f64,
    /// A small or barely seen bone keeps its own motion only when it lowers the cost at its
    /// parent's motion by at least this share. Half: on a knee pair whose target saw 8% of the
    /// fibula, its own motion lowered the cost of those few voxels by 23% while lying 1.6° from
    /// the tibia's, which it truly shared (scripts/make_pair.py, 2 mm, 20°).
    pub clear_gain: f64,
    /// The search's best candidate is weakly determined when another, this many degrees or
    /// more away, fits within `close_margin` of it.
    pub distinct_degrees: f64,
    /// See `distinct_degrees`: the runner-up's cost over the best's.
    pub close_margin: f64,
    /// A bone whose intensities correlate less than this with the target's where its motion
    /// puts it looks little like what the target holds there. On independent knee pairs
    /// (scripts/make_pair.py, 2 mm, 20° and 45°) bones at their registered motions correlated
    /// 0.93 to 0.98, and bones left 14° to 57° off -0.27 to 0.23.
    pub min_correlation: f64,
}

impl Default for FollowRules {
    fn default() -> Self {
        FollowRules {
            small_voxels: 4000.0,
            min_seen: 0.5,
            clear_gain: 0.5,
            distinct_degrees: 5.0,
            close_margin: 1.05,
            min_correlation: 0.5,
        }
    }
}

impl FollowRules {
    /// Rejects values the decision cannot use, naming the setting.
    pub fn check(&self) -> crate::error::Result<()> {
        use crate::check::within;
        let fine = within(self.small_voxels, 0.0, 1e9)
            && within(self.min_seen, 0.0, 1.0)
            && within(self.clear_gain, 0.0, 1.0)
            && within(self.distinct_degrees, 0.0, 180.0)
            && within(self.close_margin, 1.0, 10.0)
            && within(self.min_correlation, -1.0, 1.0);
        match fine {
            true => Ok(()),
            false => Err(crate::error::Error::InvalidInput(
                "init.follow: small_voxels 0 to 1e9, min_seen and clear_gain 0 to 1, \
                 distinct_degrees 0 to 180, close_margin 1 to 10, min_correlation -1 to 1"
                    .into(),
            )),
        }
    }
}

/// What the registration found for one bone, at its finest rigid level.
#[derive(Clone, Debug)]
pub struct Evidence {
    /// The bone's name.
    pub name: String,
    /// The parent's name, none for the root.
    pub parent: Option<String>,
    /// Voxels of the bone's region.
    pub voxels: f64,
    /// Mean squared residual at the bone's own motion.
    pub cost_own: f64,
    /// Correlation of the bone's intensities with the target's where its own motion puts it.
    pub correlation: f64,
    /// The same at the parent's motion.
    pub correlation_at_parent: Option<f64>,
    /// Share of the bone's voxels inside the target at its own motion.
    pub seen: f64,
    /// Mean squared residual at the parent's motion (none for the root).
    pub cost_at_parent: Option<f64>,
    /// Rotation of the own motion relative to the parent's (degrees).
    pub degrees_from_parent: Option<f64>,
    /// The chain's plausible limit on that rotation (degrees).
    pub max_degrees: f64,
    /// Best other search candidate at least `distinct_degrees` away: its cost over the best's,
    /// and how far apart they are (degrees), both at the search level.
    pub runner_up: Option<(f64, f64)>,
}

/// Which motion a bone kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Decision {
    /// The chain's root: its own motion.
    Root,
    /// Its own registration.
    Own,
    /// Its parent's motion: its own was implausible, or weak and not clearly better.
    FollowedParent,
}

/// The figures behind a bone's motion, as reported.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Confidence {
    /// Which motion was kept.
    pub decision: Decision,
    /// Why.
    pub reason: String,
    /// The parent's name.
    pub parent: Option<String>,
    /// Mean squared residual at the bone's own motion (finest rigid level).
    pub cost_own: f64,
    /// Correlation of the bone (and its one-voxel rim) with the target where the motion kept
    /// puts it: how much the moved bone looks like what the target holds there.
    pub correlation: f64,
    /// Mean squared residual at the parent's motion.
    pub cost_at_parent: Option<f64>,
    /// The search's runner-up cost over the best's (search level).
    pub runner_up_ratio: Option<f64>,
    /// Share of the bone's voxels inside the target.
    pub seen: f64,
    /// Voxels of the bone's region at the finest rigid level.
    pub voxels: f64,
    /// Rotation of its own motion relative to the parent's (degrees).
    pub degrees_from_parent: Option<f64>,
    /// What a user should look at; empty when nothing is doubtful.
    pub warnings: Vec<String>,
}

/// Decides between a bone's own motion and its parent's, and says how sure it is.
pub fn judge(e: &Evidence, rules: &FollowRules) -> Confidence {
    let mut warnings = Vec::new();
    let small = e.voxels < rules.small_voxels;
    let unseen = e.seen < rules.min_seen;
    if unseen {
        warnings.push(format!(
            "{}: only {:.0}% of it lies inside the target",
            e.name,
            100.0 * e.seen
        ));
    }
    if let Some((ratio, apart)) = e.runner_up {
        if ratio < rules.close_margin {
            warnings.push(format!(
                "{}: weakly determined, a motion {apart:.0}° away fits within {:.1}% of the best",
                e.name,
                100.0 * (ratio - 1.0)
            ));
        }
    }
    let (Some(parent), Some(at_parent), Some(degrees)) =
        (&e.parent, e.cost_at_parent, e.degrees_from_parent)
    else {
        return confidence(
            e,
            rules,
            Decision::Root,
            "the chain's root".into(),
            warnings,
        );
    };
    if degrees > e.max_degrees {
        warnings.push(format!(
            "{}: its own registration turned it {degrees:.1}° from the {parent}, beyond the \
             plausible {:.0}°; it follows the {parent}",
            e.name, e.max_degrees
        ));
        let reason = format!(
            "own motion implausible ({degrees:.1}° > {:.0}°)",
            e.max_degrees
        );
        return confidence(e, rules, Decision::FollowedParent, reason, warnings);
    }
    let gain = 1.0 - e.cost_own / at_parent;
    if (small || unseen) && gain < rules.clear_gain {
        let why = match small {
            true => format!("small ({:.0} voxels)", e.voxels),
            false => format!("{:.0}% seen", 100.0 * e.seen),
        };
        let reason = format!(
            "weak evidence ({why}) and its own motion lowers the cost by only {:.1}% (< {:.0}%)",
            100.0 * gain,
            100.0 * rules.clear_gain
        );
        return confidence(e, rules, Decision::FollowedParent, reason, warnings);
    }
    let reason = format!(
        "lowers the cost at the {parent}'s motion by {:.1}%",
        100.0 * gain
    );
    confidence(e, rules, Decision::Own, reason, warnings)
}

fn confidence(
    e: &Evidence,
    rules: &FollowRules,
    decision: Decision,
    reason: String,
    mut warnings: Vec<String>,
) -> Confidence {
    let correlation = match decision {
        Decision::FollowedParent => e.correlation_at_parent.unwrap_or(e.correlation),
        Decision::Own | Decision::Root => e.correlation,
    };
    if correlation < rules.min_correlation {
        warnings.push(format!(
            "{}: the moved bone resembles the target only weakly there (correlation \
             {correlation:.2})",
            e.name
        ));
    }
    Confidence {
        decision,
        reason,
        parent: e.parent.clone(),
        cost_own: e.cost_own,
        correlation,
        cost_at_parent: e.cost_at_parent,
        runner_up_ratio: e.runner_up.map(|r| r.0),
        seen: e.seen,
        voxels: e.voxels,
        degrees_from_parent: e.degrees_from_parent,
        warnings,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fibula() -> Evidence {
        Evidence {
            name: "fibula".into(),
            parent: Some("tibia".into()),
            voxels: 1200.0,
            cost_own: 90.0,
            correlation: 0.9,
            correlation_at_parent: Some(0.85),
            seen: 1.0,
            cost_at_parent: Some(100.0),
            degrees_from_parent: Some(3.0),
            max_degrees: 8.0,
            runner_up: None,
        }
    }

    #[test]
    fn a_small_bone_follows_its_parent_unless_it_clearly_fits_better() {
        let rules = FollowRules::default();
        let weak = judge(&fibula(), &rules);
        assert_eq!(weak.decision, Decision::FollowedParent, "{}", weak.reason);
        assert!(weak.warnings.is_empty());
        let clear = judge(
            &Evidence {
                cost_own: 40.0,
                ..fibula()
            },
            &rules,
        );
        assert_eq!(clear.decision, Decision::Own, "{}", clear.reason);
        let large = judge(
            &Evidence {
                voxels: 50_000.0,
                ..fibula()
            },
            &rules,
        );
        assert_eq!(large.decision, Decision::Own);
    }

    #[test]
    fn an_implausible_turn_follows_the_parent_and_warns() {
        let e = Evidence {
            cost_own: 10.0,
            degrees_from_parent: Some(44.0),
            voxels: 50_000.0,
            ..fibula()
        };
        let c = judge(&e, &FollowRules::default());
        assert_eq!(c.decision, Decision::FollowedParent);
        assert!(
            c.warnings[0].contains("44.0° from the tibia"),
            "{:?}",
            c.warnings
        );
    }

    #[test]
    fn a_barely_seen_bone_or_a_close_runner_up_warns() {
        let e = Evidence {
            seen: 0.4,
            runner_up: Some((1.01, 30.0)),
            voxels: 50_000.0,
            cost_own: 10.0,
            ..fibula()
        };
        let c = judge(&e, &FollowRules::default());
        assert_eq!(c.decision, Decision::Own);
        assert_eq!(c.warnings.len(), 2, "{:?}", c.warnings);
        let root = judge(
            &Evidence {
                parent: None,
                cost_at_parent: None,
                degrees_from_parent: None,
                ..fibula()
            },
            &FollowRules::default(),
        );
        assert_eq!(root.decision, Decision::Root);
    }

    #[test]
    fn a_bone_that_does_not_look_like_the_target_there_warns() {
        let followed = judge(
            &Evidence {
                correlation_at_parent: Some(0.2),
                ..fibula()
            },
            &FollowRules::default(),
        );
        assert_eq!(followed.decision, Decision::FollowedParent);
        assert_eq!(followed.correlation, 0.2);
        assert!(
            followed.warnings[0].contains("correlation 0.20"),
            "{:?}",
            followed.warnings
        );
        assert!(judge(&fibula(), &FollowRules::default())
            .warnings
            .is_empty());
    }
}
