//! The per-bone rigid registration: each bone's candidate motions searched about the flexion
//! axis, refined coarse to fine, judged against its parent's motion, in chain order.

use crate::abi::ThresholdParams;
use crate::backend::{Backend, DeviceImage};
use crate::error::{Error, Result};
use crate::images::pyramid;
use crate::images::regions;
use crate::init::rigid::{
    refine, score_candidates, score_covered, BoneLevel, LevelReport, RefineOptions,
};
use crate::io::transform::BoneTransforms;
use crate::joints::chain::{self, Link};
use crate::joints::confidence::{judge, Decision, Evidence};
use crate::joints::joint::{degrees_between, rotation_about, rotation_degrees, JointAxis};
use crate::progress::Progress;
use crate::volume::Affine;
use nalgebra::{Rotation3, Unit, Vector3};

use super::*;

/// Candidate motions of a bone: rotations by `range` about the flexion axis (and about axes
/// tilted from it by `tilt_degrees`) through the condyles, after its parent's motion.
fn candidates(
    axis: &JointAxis,
    parent: &Affine,
    [from, to, step]: [f64; 3],
    tilt_degrees: f64,
) -> Vec<(f64, Affine)> {
    let tilt = tilt_degrees.to_radians();
    let tilted = |about: Vector3<f64>, t: f64| {
        Rotation3::from_axis_angle(&Unit::new_normalize(about), t) * axis.direction
    };
    let directions = [
        axis.direction,
        tilted(axis.long_axis, tilt),
        tilted(axis.long_axis, -tilt),
        tilted(axis.anterior, tilt),
        tilted(axis.anterior, -tilt),
    ];
    let angles: Vec<f64> = (0..)
        .map(|k| from + k as f64 * step)
        .take_while(|a| *a <= to + 1e-9)
        .collect();
    directions
        .iter()
        .flat_map(|d| {
            let a = JointAxis {
                direction: *d,
                ..*axis
            };
            angles
                .iter()
                .map(move |&deg| (deg, parent * rotation_about(&a, deg)))
        })
        .collect()
}

/// A bone's region at one pyramid level: its mask where the backend computes, and what the
/// host loop needs of it.
struct RegionLevel<B: Backend> {
    mask: DeviceImage<B>,
    /// Voxels inside (mask ≥ 0.5).
    inside: usize,
    /// Their centroid (world mm): the centre rotations are linearised about.
    centroid: Vector3<f64>,
}

impl<B: Backend> RegionLevel<B> {
    fn new(backend: &B, mask: DeviceImage<B>) -> Result<Self> {
        let region = regions::moments(backend, &mask, 0.5)?;
        Ok(RegionLevel {
            mask,
            inside: region.voxels,
            centroid: region.centroid,
        })
    }
}

/// A bone's region (label dilated, InitOptions::dilation_mm) on the pyramid levels from `first`
/// on.
struct Region<B: Backend> {
    first: usize,
    levels: Vec<RegionLevel<B>>,
}

impl<B: Backend> Region<B> {
    fn new(
        backend: &B,
        labels: &DeviceImage<B>,
        code: u16,
        levels: usize,
        first: usize,
        options: &InitOptions,
    ) -> Result<Self> {
        let indicator = regions::label_index(backend, labels, &[code])?;
        let mut down = pyramid::build(backend, indicator, first + 1)?;
        let at_first = down.pop().expect("level 0 at least");
        // The bone at this level (smoothed indicator ≥ ½), grown by the margin.
        let distance = regions::distance_maps(backend, &at_first, 1)?;
        let grid = at_first.grid;
        let margin = options.dilation_mm + options.dilation_voxels * grid.finest_spacing();
        // A micrometre more, so that a neighbour exactly `margin` away is in on both backends.
        let within = ThresholdParams::new(&grid, (margin + 1e-3) as f32);
        let nothing_held = backend.zeros("nothing held", grid.len())?;
        let dilated = DeviceImage {
            data: backend.mark_at_most(&within, &distance, &nothing_held)?,
            grid,
        };
        let levels = pyramid::build(backend, dilated, levels - first)?
            .into_iter()
            .map(|mask| RegionLevel::new(backend, mask))
            .collect::<Result<_>>()?;
        Ok(Region { first, levels })
    }

    /// The region at absolute pyramid level `level` (≥ first).
    fn at(&self, level: usize) -> &RegionLevel<B> {
        &self.levels[level - self.first]
    }
}

/// A pair's pyramids, where the backend computes.
struct Pyramids<B: Backend> {
    source: Vec<DeviceImage<B>>,
    target: Vec<DeviceImage<B>>,
}

impl<B: Backend> Pyramids<B> {
    fn level<'a>(&'a self, level: usize, region: &'a Region<B>) -> BoneLevel<'a, B> {
        BoneLevel {
            source: &self.source[level],
            mask: &region.at(level).mask,
            target: &self.target[level],
        }
    }
}

/// How one bone's own registration went.
struct BoneFit {
    /// Flexion angle of the search candidate it came from.
    search_degrees: Option<f64>,
    /// Refinement per level, coarse to fine.
    levels: Vec<LevelReport>,
    /// The best refined candidate at least `distinct_degrees` from the winner: its cost over
    /// the winner's and the angle between them.
    runner_up: Option<(f64, f64)>,
}

/// The search candidates to refine: the best-scoring three that lie at least `basin_degrees`
/// apart, so that a second minimum gets a refinement of its own.
fn distinct_best(cands: &[(f64, Affine)], scores: &[f64], basin_degrees: f64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..cands.len())
        .filter(|&k| scores[k].is_finite())
        .collect();
    order.sort_by(|&a, &b| scores[a].total_cmp(&scores[b]));
    let mut kept: Vec<usize> = Vec::new();
    for k in order {
        let apart = |j: &usize| degrees_between(&cands[*j].1, &cands[k].1) >= basin_degrees;
        if kept.iter().all(apart) {
            kept.push(k);
        }
        if kept.len() == 3 {
            break;
        }
    }
    kept
}

/// The search's outcome: the best refined candidate.
struct Searched {
    motion: Affine,
    /// The flexion angle it started from.
    degrees: f64,
    report: LevelReport,
    /// The best other refined candidate at least `distinct_degrees` away: its cost over the
    /// best's and the angle between them.
    runner_up: Option<(f64, f64)>,
}

/// Refines the best search candidates of distinct basins at `level` (`options`' basin
/// degrees apart), keeping the best fit and the runner-up's cost ratio and angle.
fn search<B: Backend>(
    backend: &B,
    level: &BoneLevel<B>,
    centroid: &Vector3<f64>,
    cands: &[(f64, Affine)],
    options: &InitOptions,
) -> Result<Option<Searched>> {
    let motions: Vec<Affine> = cands.iter().map(|c| c.1).collect();
    let scores = score_candidates(backend, level, &motions)?;
    let mut refined = Vec::new();
    for k in distinct_best(cands, &scores, options.search_basin_degrees) {
        let (m, report) = refine(
            backend,
            level,
            cands[k].1,
            centroid,
            &RefineOptions::default(),
        )?;
        refined.push((m, cands[k].0, report));
    }
    refined.sort_by(|a, b| a.2.cost_after.total_cmp(&b.2.cost_after));
    let Some(best) = refined.first() else {
        return Ok(None);
    };
    let runner_up = refined[1..]
        .iter()
        .map(|r| {
            (
                r.2.cost_after / best.2.cost_after,
                degrees_between(&best.0, &r.0),
            )
        })
        .find(|r| r.1 >= options.follow.distinct_degrees);
    let (motion, degrees, report) = refined.swap_remove(0);
    Ok(Some(Searched {
        motion,
        degrees,
        report,
        runner_up,
    }))
}

/// Registers one bone from `start` through the levels coarse to fine, after an optional
/// search at its coarsest usable level.
fn register_bone<B: Backend>(
    backend: &B,
    code: u16,
    pyramids: &Pyramids<B>,
    region: &Region<B>,
    start: Affine,
    cands: Option<Vec<(f64, Affine)>>,
    options: &InitOptions,
) -> Result<(Affine, BoneFit)> {
    let first = region.first;
    let coarsest = (first..first + region.levels.len())
        .rev()
        .find(|&l| region.at(l).inside >= options.search_min_voxels)
        .unwrap_or(first);
    let mut motion = start;
    let mut fit = BoneFit {
        search_degrees: None,
        levels: Vec::new(),
        runner_up: None,
    };
    if let Some(cands) = cands {
        let level = pyramids.level(coarsest, region);
        let centroid = region.at(coarsest).centroid;
        let found = search(backend, &level, &centroid, &cands, options)?;
        let best = found.ok_or_else(|| {
            Error::InvalidInput(format!(
                "bone {code}: no search candidate overlaps the target"
            ))
        })?;
        motion = best.motion;
        fit.search_degrees = Some(best.degrees);
        fit.runner_up = best.runner_up;
        fit.levels.push(best.report);
    }
    let searched = fit.search_degrees.is_some();
    let range: Vec<usize> = match (searched, coarsest == first) {
        (true, true) => Vec::new(),
        (true, false) => (first..coarsest).rev().collect(),
        (false, _) => (first..=coarsest).rev().collect(),
    };
    for l in range {
        let centroid = region.at(l).centroid;
        let level = pyramids.level(l, region);
        let (refined, report) = refine(
            backend,
            &level,
            motion,
            &centroid,
            &RefineOptions::default(),
        )?;
        motion = refined;
        fit.levels.push(report);
    }
    Ok((motion, fit))
}

/// The evidence for a bone's own motion against its parent's, at its finest rigid level.
fn evidence<B: Backend>(
    backend: &B,
    pyramids: &Pyramids<B>,
    region: &Region<B>,
    link: &Link,
    own: &Affine,
    parent: Option<(String, Affine)>,
    runner_up: Option<(f64, f64)>,
) -> Result<Evidence> {
    let finest = region.at(region.first);
    let level = pyramids.level(region.first, region);
    let mut motions = vec![*own];
    motions.extend(parent.as_ref().map(|p| p.1));
    let scores = score_covered(backend, &level, &motions)?;
    let voxels = finest.inside as f64;
    Ok(Evidence {
        name: link.name.clone(),
        voxels,
        cost_own: scores[0].cost,
        correlation: scores[0].correlation,
        correlation_at_parent: scores.get(1).map(|s| s.correlation),
        seen: scores[0].voxels / voxels.max(1.0),
        cost_at_parent: scores.get(1).map(|s| s.cost),
        degrees_from_parent: parent.as_ref().map(|p| degrees_between(&p.1, own)),
        parent: parent.map(|p| p.0),
        max_degrees: link.max_degrees,
        runner_up,
    })
}

/// The motions `given` holds for `bones`, in `bones` order.
pub(super) fn given_motions(given: &BoneTransforms, bones: &[u16]) -> Result<Vec<(u16, Affine)>> {
    bones
        .iter()
        .map(|b| {
            given
                .bones
                .iter()
                .find(|t| t.label == *b)
                .map(|t| (*b, t.affine()))
                .ok_or_else(|| {
                    Error::InvalidInput(format!("--init has no transform for bone label {b}"))
                })
        })
        .collect()
}

/// The pair's pyramids for the rigid stage, and the finest level it registers at.
fn rigid_pyramids<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    options: &InitOptions,
) -> Result<(Pyramids<B>, usize)> {
    let mut pyramids = Pyramids {
        source: pyramid::build(backend, pair.source.clone(), options.levels)?,
        target: pyramid::build(backend, pair.target.clone(), options.levels)?,
    };
    let levels = pyramids.source.len().min(pyramids.target.len());
    pyramids.source.truncate(levels);
    let first = pyramids
        .source
        .iter()
        .position(|v| v.grid.finest_spacing() >= options.finest_spacing_mm - 1e-9)
        .unwrap_or(levels - 1)
        .min(levels - 1);
    Ok((pyramids, first))
}

/// Registers `bones` down the chain: each from its parent's motion (the root from the
/// identity), searched relative to it where its link says so, then judged against it: a bone
/// whose own motion is implausible, or weakly supported and not clearly better, keeps its
/// parent's. Motions and reports come back in `bones` order.
#[allow(clippy::type_complexity)] // two parallel lists, as Initialisation holds them
pub(super) fn register_bones<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    (axis, seeds): (&JointAxis, Option<&BoneTransforms>),
    bones: &[u16],
    options: &InitOptions,
    progress: &dyn Progress,
) -> Result<(Vec<(u16, Affine)>, Vec<BoneReport>)> {
    let (pyramids, first) = rigid_pyramids(backend, pair, options)?;
    let levels = pyramids.source.len();
    let mut found: Vec<(u16, Affine, BoneReport)> = Vec::new();
    for code in chain::registration_order(&options.chain, bones)? {
        let link = chain::link(&options.chain, code).expect("registration_order checked it");
        let parent = chain::parent_among(&options.chain, code, bones).map(|p| {
            let at = found.iter().find(|f| f.0 == p).expect("parents go first");
            (options.name_of(p), at.1)
        });
        let seed = seeds.and_then(|s| s.bones.iter().find(|b| b.label == code));
        let seed = seed.map(|b| b.affine());
        let start = match (&parent, seed) {
            (Some(p), _) => p.1,
            (None, seed) => seed.unwrap_or_else(Affine::identity),
        };
        let cands = match (link.search_degrees, &parent) {
            (Some(range), Some(_)) => {
                let mut all = candidates(axis, &start, range, options.search_tilt_degrees);
                all.extend(seed.map(|s| (degrees_between(&start, &s), s)));
                Some(all)
            }
            _ => None,
        };
        let region = Region::new(backend, &pair.labels, code, levels, first, options)?;
        let (own, fit) = register_bone(backend, code, &pyramids, &region, start, cands, options)?;
        let evidence = evidence(
            backend,
            &pyramids,
            &region,
            link,
            &own,
            parent,
            fit.runner_up,
        )?;
        let confidence = judge(&evidence, &options.follow);
        let motion = match confidence.decision {
            Decision::FollowedParent => start,
            Decision::Own | Decision::Root => own,
        };
        progress.step(&format!(
            "{} turned {:.1}° ({})",
            link.name,
            rotation_degrees(&motion),
            confidence.reason
        ));
        let report = BoneReport {
            label: code,
            name: link.name.clone(),
            search_degrees: fit.search_degrees,
            levels: fit.levels,
            confidence,
        };
        found.push((code, motion, report));
    }
    let mut motions = Vec::new();
    let mut reports = Vec::new();
    for b in bones {
        let at = found.iter().position(|f| f.0 == *b).expect("registered");
        let (code, motion, report) = found.swap_remove(at);
        motions.push((code, motion));
        reports.push(report);
    }
    Ok((motions, reports))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The patella's search scores along the flexion axis on the half phantom bent 90° by
    /// scripts/make_pair.py (seed 22), measured at its coarsest level, 4° apart from −30°
    /// to 150°. The cost has two basins: the wrong one around 130° scores lower than the right
    /// one around 74° (truth 63°), whose refined fit is 2.8 times better.
    const PATELLA_SCORES: [f64; 46] = [
        89626.0, 91322.0, 92586.0, 93672.0, 94311.0, 94728.0, 94775.0, 94646.0, 95514.0, 95830.0,
        95691.0, 95632.0, 95870.0, 96101.0, 96296.0, 96504.0, 96402.0, 96428.0, 96584.0, 95296.0,
        92333.0, 86610.0, 78750.0, 68011.0, 57574.0, 49914.0, 46645.0, 52524.0, 60834.0, 74434.0,
        80204.0, 88344.0, 94424.0, 91826.0, 87042.0, 78220.0, 66907.0, 55084.0, 43865.0, 36491.0,
        36304.0, 39425.0, 43528.0, 46200.0, 49012.0, 49112.0,
    ];

    fn patella_line() -> Vec<(f64, Affine)> {
        let axis = JointAxis {
            point: Vector3::new(0.8, 16.2, 13.7),
            direction: Vector3::x(),
            long_axis: Vector3::z(),
            anterior: Vector3::y(),
        };
        let range = [-30.0, 150.0, 4.0];
        candidates(&axis, &Affine::identity(), range, 0.0)
            .into_iter()
            .take(PATELLA_SCORES.len())
            .collect()
    }

    #[test]
    fn each_basin_of_the_search_gets_a_refinement() {
        let line = patella_line();
        let angles = |kept: Vec<usize>| -> Vec<f64> { kept.iter().map(|&k| line[k].0).collect() };
        let basin = InitOptions::default().search_basin_degrees;
        let kept = angles(distinct_best(&line, &PATELLA_SCORES, basin));
        assert_eq!(kept[0], 130.0, "the lowest score first: {kept:?}");
        assert!(kept.contains(&74.0), "the second basin's best: {kept:?}");
        // Candidates merely a few degrees apart all lie in the wrong basin.
        let close = angles(distinct_best(&line, &PATELLA_SCORES, 5.0));
        assert!(
            close.iter().all(|a| (120.0..=140.0).contains(a)),
            "{close:?}"
        );
    }
}
