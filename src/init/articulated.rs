//! Articulated initialisation (paper §2): per-bone rigid registration coarse to fine, skinning
//! weights, and the inverted volume skeletal deformation, giving the initial field u0.

use crate::abi::{Blending, Interpolation, ResampleParams, ThresholdParams};
use crate::backend::{Backend, DeviceImage};
use crate::check::{check_ranges, Range};
use crate::error::{Error, Result};
use crate::images::fold_repair::{FoldRepair, SourceLabels};
use crate::images::pyramid;
use crate::images::regions;
use crate::init::reach::{self, ReachChoice};
use crate::init::rigid::{
    refine, score_candidates, score_covered, BoneLevel, LevelReport, RefineOptions,
};
use crate::init::skinning;
use crate::init::vsd::{initial_field, InitialField};
use crate::io::transform::{BoneTransform, BoneTransforms};
use crate::joints::anatomy::Side;
use crate::joints::chain::{self, Link};
use crate::joints::confidence::{judge, Confidence, Decision, Evidence, FollowRules};
use crate::joints::joint::{
    degrees_between, flexion_axis, rotation_about, rotation_degrees, JointAxis, KneeBones,
};
use crate::joints::kinematics::{knee_kinematics, KneeKinematics};
use crate::labels as label;
use crate::levels::MAX_LEVELS;
use crate::progress::Progress;
use crate::volume::{Affine, Field, Grid, Image, Labels, Volume};
use nalgebra::{Rotation3, Unit, Vector3};

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

/// One bone's outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BoneReport {
    /// Label code.
    pub label: u16,
    /// Name.
    pub name: String,
    /// Flexion angle of the best search candidate (degrees), when searched.
    pub search_degrees: Option<f64>,
    /// Refinement per level, coarse to fine.
    pub levels: Vec<LevelReport>,
    /// Which motion the bone kept and how sure that is.
    pub confidence: Confidence,
}

/// What the initialisation found (its images stay where the backend computes:
/// [`InitialImages`]).
pub struct Initialisation {
    /// Bone motions, source → target (RAS), in `bones` order.
    pub motions: Vec<(u16, Affine)>,
    /// The flexion axis found from the labels.
    pub axis: JointAxis,
    /// The bones skinned, in weight order.
    pub bones: Vec<u16>,
    /// The grid the skinning weights live on.
    pub weight_grid: Grid,
    /// Folds of the blend removed from the initial field.
    pub repair: FoldRepair,
    /// How far small segments reach, and why (crate::init::reach).
    pub reach: ReachChoice,
    /// Per-bone reports.
    pub reports: Vec<BoneReport>,
}

/// The initialisation's images, where the backend computes.
pub struct InitialImages<B: Backend> {
    /// u0: target point p → source point p + u0(p), world RAS mm (3 values per voxel).
    pub field: DeviceImage<B>,
    /// The blend's inversion residual per target voxel (mm).
    pub residual: DeviceImage<B>,
    /// The source moved by the initial field, on the target grid.
    pub initialised: DeviceImage<B>,
}

/// The initialisation's images on the host: what `posereg init` writes.
pub struct InitialVolumes {
    /// u0: target point p → source point p + u0(p), world RAS mm.
    pub field: Field,
    /// The blend's inversion residual per target voxel (mm).
    pub residual: Volume,
    /// The source moved by the initial field, on the target grid.
    pub initialised: Volume,
}

impl<B: Backend> InitialImages<B> {
    /// Brings the three images back (one wait).
    pub fn download(&self, backend: &B) -> Result<InitialVolumes> {
        let mut out = backend.download(&[
            &self.field.data,
            &self.residual.data,
            &self.initialised.data,
        ])?;
        let grid = &self.field.grid;
        let (initialised, residual) =
            (out.pop().unwrap_or_default(), out.pop().unwrap_or_default());
        let field = out.pop().unwrap_or_default();
        Ok(InitialVolumes {
            field: Image::from_data(grid.clone(), bytemuck::cast_vec(field))?,
            residual: Image::from_data(grid.clone(), residual)?,
            initialised: Image::from_data(grid.clone(), initialised)?,
        })
    }
}

/// A pair's images where the backend computes, uploaded once for a whole registration.
pub struct PairImages<B: Backend> {
    /// The source (straight) scan.
    pub source: DeviceImage<B>,
    /// Its bone labels, codes as f32.
    pub labels: DeviceImage<B>,
    /// The target (bent) scan.
    pub target: DeviceImage<B>,
}

impl<B: Backend> PairImages<B> {
    /// Uploads the three images.
    pub fn upload(backend: &B, source: &Volume, labels: &Labels, target: &Volume) -> Result<Self> {
        Ok(PairImages {
            source: DeviceImage::upload(backend, "source", source.clone())?,
            labels: DeviceImage::upload_labels(backend, labels)?,
            target: DeviceImage::upload(backend, "target", target.clone())?,
        })
    }
}

impl Initialisation {
    /// The bone motions in the on-disk format, named as `options`' chain names them.
    pub fn transforms(&self, options: &InitOptions) -> BoneTransforms {
        transforms_of(&self.motions, options)
    }

    /// The knee's kinematics of these bone motions (frames from the source's `labels`), each
    /// joint with its bones' registration confidence; None, with the reason among the
    /// warnings, when they cannot be told (no femur or tibia, frames that cannot be measured).
    pub fn kinematics(
        &self,
        labels: &Labels,
        chain: &[Link],
        side: Option<Side>,
    ) -> Result<(Option<KneeKinematics>, Vec<String>)> {
        let (kinematics, warnings) = knee_kinematics(labels, chain, &self.motions, side)?;
        let confidence = |bone: &str| {
            let report = self.reports.iter().find(|r| r.name == bone);
            report.map(|r| r.confidence.clone())
        };
        Ok((kinematics.map(|k| k.with_confidence(confidence)), warnings))
    }
}

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
fn given_motions(given: &BoneTransforms, bones: &[u16]) -> Result<Vec<(u16, Affine)>> {
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
fn register_bones<B: Backend>(
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

/// Where the bones' rigid registration starts from, when not from the identity.
#[derive(Clone, Copy, Debug)]
pub enum Start<'a> {
    /// These motions, kept as they are: the rigid stage is skipped (`--init`).
    Given(&'a BoneTransforms),
    /// These motions as first guesses beside the search's (a neighbouring pose's result): a
    /// root starts from its own, a searched bone scores it among its candidates.
    Seeded(&'a BoneTransforms),
    /// A pose reached through the one before it: motions and initial field given, neither the
    /// rigid stage nor the blend run.
    Chained(&'a Chained),
}

impl Start<'_> {
    /// How the bones' registration started, in words (report.json's `inputs.start`).
    pub fn describe(start: Option<Start>) -> &'static str {
        match start {
            None => "identity: each bone found by its rotation search",
            Some(Start::Given(_)) => "given: the bones' motions as --init gave them",
            Some(Start::Seeded(_)) => "seeded: the previous pose's bone motions tried first",
            Some(Start::Chained(_)) => {
                "chained: bones registered with the previous pose's motions tried first, the \
                 tissue reached through the previous pose's registration"
            }
        }
    }
}

/// A pose reached through its neighbour in a series (`posereg series`): the bone motions, the
/// initial field composed along the series, and the reports of the bones' registration.
#[derive(Clone, Debug)]
pub struct Chained {
    /// Bone motions, source → this pose (RAS).
    pub motions: BoneTransforms,
    /// Initial field on this pose's grid: its point → source point (RAS mm).
    pub field: Field,
    /// The bones' registration from the source (the neighbouring pose's motions tried first).
    pub reports: Vec<BoneReport>,
}

/// Runs the articulated initialisation on `pair` (`labels`: its label map on the host), from
/// the identity or from `start`.
pub fn initialise<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    labels: &Labels,
    options: &InitOptions,
    start: Option<Start>,
    progress: &dyn Progress,
) -> Result<(Initialisation, InitialImages<B>)> {
    let (bones, axis) = bones_and_axis(pair, labels, options)?;
    let rigid_steps = match start {
        Some(Start::Given(_) | Start::Chained(_)) => 0,
        _ => bones.len(),
    };
    progress.begin("initialisation", rigid_steps + 1);
    let registered =
        |seeds| register_bones(backend, pair, (&axis, seeds), &bones, options, progress);
    let (motions, reports) = match start {
        Some(Start::Given(given)) => (given_motions(given, &bones)?, Vec::new()),
        Some(Start::Chained(c)) => (given_motions(&c.motions, &bones)?, c.reports.clone()),
        Some(Start::Seeded(seeds)) => registered(Some(seeds))?,
        None => registered(None)?,
    };
    let target = &pair.target.grid;
    let (initial, reach) = match start {
        Some(Start::Chained(c)) => (chained_field(backend, c, target)?, ReachChoice::default()),
        _ => {
            let matrices: Vec<Affine> = motions.iter().map(|m| m.1).collect();
            let source_labels = SourceLabels {
                host: labels,
                device: &pair.labels,
            };
            let judge = reach::Judge::new(&pair.source, &pair.target);
            let blend = Blend {
                labels: &source_labels,
                bones: &bones,
                matrices: &matrices,
                options,
            };
            blend.field(backend, target, (&judge, &|field| Ok(field)))?
        }
    };
    let resample = ResampleParams::new(&pair.source.grid, target, 0.0, Interpolation::Linear);
    let initialised = DeviceImage {
        data: backend.resample(&resample, &pair.source.data, &initial.field.data)?,
        grid: target.clone(),
    };
    progress.step("skinning weights and volume skeletal deformation");
    progress.end();
    let found = Initialisation {
        motions,
        axis,
        weight_grid: skinning::skinning_grid(&pair.labels.grid).0,
        bones,
        repair: initial.repair,
        reach,
        reports,
    };
    let images = InitialImages {
        field: initial.field,
        residual: initial.residual,
        initialised,
    };
    Ok((found, images))
}

/// Bone motions to blend across the soft tissue of a label map.
struct Blend<'a, B: Backend> {
    labels: &'a SourceLabels<'a, B>,
    /// The bones, in weight order.
    bones: &'a [u16],
    /// Their motions, in `bones` order.
    matrices: &'a [Affine],
    options: &'a InitOptions,
}

/// Brings a field on the judging grid (its point → the blend's label map) to the source
/// scan, for [`reach::choose`].
pub type ToSource<'a, B> = &'a dyn Fn(DeviceImage<B>) -> Result<DeviceImage<B>>;

impl<B: Backend> Blend<'_, B> {
    /// The blend inverted on `target`, its folds repaired, with the reach limit
    /// [`reach::choose`] keeps from `options.reach` (each candidate's field brought to the
    /// source by `to_source` and scored by `judge`): the initial field where the backend
    /// computes.
    fn field(
        &self,
        backend: &B,
        target: &Grid,
        (judge, to_source): (&reach::Judge<B>, ToSource<B>),
    ) -> Result<(InitialField<B>, ReachChoice)> {
        let distances =
            skinning::distances(backend, self.labels.device, self.bones, Some(self.matrices))?;
        let field_on = |limit: f64, grid: &Grid| {
            let weights = distances.weights(backend, skinning::SHEPARD_POWER, limit)?;
            let blend = self.options.blending;
            initial_field(backend, &weights, self.labels, self.matrices, blend, grid)
        };
        let choice = reach::choose(backend, &self.options.reach, judge, |limit, grid| {
            to_source(field_on(limit, grid)?.field)
        })?;
        Ok((field_on(choice.limit, target)?, choice))
    }
}

/// The blend of given bone `motions` across the soft tissue of a label map (one carried into
/// another pose, not necessarily a scan's own), inverted on `target`, as [`initialise`] blends
/// the motions it found: the field where the backend computes. For the step between two
/// poses of a series; `judge` and `to_source` choose the reach as [`Blend::field`] does.
pub fn blend_motions<B: Backend>(
    backend: &B,
    labels: &Labels,
    motions: &BoneTransforms,
    options: &InitOptions,
    target: &Grid,
    judge: (&reach::Judge<B>, ToSource<B>),
) -> Result<DeviceImage<B>> {
    let bones = options.bones_in(labels);
    if bones.is_empty() {
        return Err(Error::InvalidInput(
            "no bone of the label map lies on its grid: nothing to blend".into(),
        ));
    }
    let matrices: Vec<Affine> = given_motions(motions, &bones)?
        .into_iter()
        .map(|m| m.1)
        .collect();
    let device = DeviceImage::upload_labels(backend, labels)?;
    let source_labels = SourceLabels {
        host: labels,
        device: &device,
    };
    let blend = Blend {
        labels: &source_labels,
        bones: &bones,
        matrices: &matrices,
        options,
    };
    Ok(blend.field(backend, target, judge)?.0.field)
}

/// A chained pose's initial field where the backend computes, with no blend residual and no
/// repair (the blend ran in the poses it was composed from).
fn chained_field<B: Backend>(
    backend: &B,
    chained: &Chained,
    target: &Grid,
) -> Result<InitialField<B>> {
    if !chained.field.grid.same_as(target, 1e-3) {
        return Err(Error::InvalidInput(
            "the chained initial field is not on the target's grid".into(),
        ));
    }
    Ok(InitialField {
        field: DeviceImage::upload_field(backend, "chained initial field", chained.field.clone())?,
        residual: DeviceImage {
            data: backend.zeros("no blend residual", target.len())?,
            grid: target.clone(),
        },
        repair: FoldRepair::default(),
    })
}

/// The bones `options` registers in `labels` (on the source's grid) and the knee's flexion
/// axis, or why the labels cannot be registered.
fn bones_and_axis<B: Backend>(
    pair: &PairImages<B>,
    labels: &Labels,
    options: &InitOptions,
) -> Result<(Vec<u16>, JointAxis)> {
    options.check()?;
    if !labels.grid.same_as(&pair.source.grid, 1e-3) {
        return Err(Error::InvalidInput(
            "the label map is not on the source image's grid".into(),
        ));
    }
    let bones = options.bones_in(labels);
    for b in &bones {
        if !labels.data.contains(b) {
            return Err(Error::InvalidInput(format!(
                "bone label {b} has no voxels in the label map"
            )));
        }
    }
    if bones.is_empty() {
        return Err(Error::InvalidInput(
            "the label map has no bone labels (2 femur, 3 tibia, 4 patella, 5 fibula)".into(),
        ));
    }
    crate::abi::check_bone_count(bones.len())?;
    let axis = flexion_axis(labels, KneeBones::of_chain(&options.chain)?)?;
    Ok((bones, axis))
}

/// The bones' rigid registration alone, without the blend: each bone's motion (source →
/// target) and report, in the order `options` registers them, `seeds` tried first.
pub fn bone_motions<B: Backend>(
    backend: &B,
    (source, labels, target): (&Volume, &Labels, &Volume),
    options: &InitOptions,
    seeds: Option<&BoneTransforms>,
    progress: &dyn Progress,
) -> Result<(BoneTransforms, Vec<BoneReport>)> {
    let pair = PairImages::upload(backend, source, labels, target)?;
    let (bones, axis) = bones_and_axis(&pair, labels, options)?;
    progress.begin("bones", bones.len());
    let (motions, reports) =
        register_bones(backend, &pair, (&axis, seeds), &bones, options, progress)?;
    progress.end();
    Ok((transforms_of(&motions, options), reports))
}

/// Bone motions in the bone-transform format, named as the chain names them.
fn transforms_of(motions: &[(u16, Affine)], options: &InitOptions) -> BoneTransforms {
    BoneTransforms::new(
        motions
            .iter()
            .map(|(code, m)| BoneTransform::new(*code, &options.name_of(*code), m))
            .collect(),
    )
}

/// [`initialise`] from host volumes to host volumes: the pair goes up once, the three images
/// come back once (what `posereg init` writes).
pub fn initialise_volumes<B: Backend>(
    backend: &B,
    source: &Volume,
    labels: &Labels,
    target: &Volume,
    options: &InitOptions,
    start: Option<Start>,
    progress: &dyn Progress,
) -> Result<(Initialisation, InitialVolumes)> {
    let pair = PairImages::upload(backend, source, labels, target)?;
    let (found, images) = initialise(backend, &pair, labels, options, start, progress)?;
    Ok((found, images.download(backend)?))
}

/// A field that moves every point by one rigid motion (source → target), on `grid`: what
/// aligning a single bone gives the whole volume.
pub fn rigid_field(motion: &Affine, grid: &crate::volume::Grid) -> Result<Field> {
    let inverse = motion
        .try_inverse()
        .ok_or_else(|| Error::InvalidInput("motion is singular".into()))?;
    let data = (0..grid.len())
        .map(|n| {
            let w = grid.world_of(n);
            let q = inverse * nalgebra::Vector4::new(w[0], w[1], w[2], 1.0);
            [
                (q.x - w[0]) as f32,
                (q.y - w[1]) as f32,
                (q.z - w[2]) as f32,
            ]
        })
        .collect();
    Image::from_data(grid.clone(), data)
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
