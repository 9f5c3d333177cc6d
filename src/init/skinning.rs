//! Skinning weights w_j(x): a partition of unity over the bones, exactly 1 inside bone j and 0
//! inside the others, smooth across soft tissue.
//!
//! Method: normalised inverse-distance (Shepard) weights, w_j ∝ d_j⁻⁵, from exact Euclidean
//! distance maps of each bone label (regions::distance_maps), scaled by the size of the
//! segment the bone moves with ([`reach_scale`], [`segments`]). Chosen over harmonic weights
//! because they need no solve (one kernel pass), are exact at the bones by construction, and
//! depend only on the labels and the motions; their drawback — weights are not volume-aware, so
//! tissue far from every bone blends by relative distance alone — is left to the adaptive stage,
//! which does not always reach it (at large flexion, in front of the knee: BENCHMARKS.md). Weights live on a skinning grid of about 2.5 mm (a stride of the source grid), small
//! enough to bind whole on any device; they are interpolated trilinearly, so a bone is exactly
//! rigid except within one skinning voxel of its surface.

use crate::abi::{Interpolation, ResampleParams, SkinWeightsParams};
use crate::backend::{Backend, DeviceImage};
use crate::error::{Error, Result};
use crate::images::regions;
use crate::volume::{Affine, Grid};
use nalgebra::Vector3;

/// Spacing the skinning grid aims for (mm).
pub const SKIN_SPACING_MM: f64 = 2.5;
/// Shepard exponent. With 2 the weights' tails are long: at 60° the upper thigh, 30 mm from the
/// femur and 200 mm from the turned tibia, kept ~2% of the tibia's motion, 4 mm of error in the
/// initial field where the truth is still (half phantom end to end, 2 → 4: 30° 2.05 → 1.26 mm,
/// 60° 2.12 → 1.86 mm). 5 against 4, measured once the reach was chosen per pair, on two truths
/// that share nothing but the bones' rigidity (BENCHMARKS.md, "The skinning's falloff"): the
/// initial field is as close or closer on all six pairs (half phantom 30° / 60° / 90°: 0.55 /
/// 1.05 / 1.65 → 0.53 / 0.98 / 1.65 mm), and the knee bent by the independent generator ends
/// 0.1–0.3 mm closer at 45° and 90° (2 mm 45°: 1.05 → 0.87 mm); 6 put the phantom's initial
/// field farther off (1.09 / 1.77 mm at 60° / 90°), 8 the knee's final field at 45° (1.02 mm).
pub const SHEPARD_POWER: u32 = 5;

/// Weights of several bones on a grid, where the backend computes.
pub struct SkinningWeights<B: Backend> {
    /// Where the weights are.
    pub grid: Grid,
    /// Bone label codes, in weight order.
    pub bones: Vec<u16>,
    /// bones.len() floats per voxel, x fastest.
    pub data: B::Buffer<f32>,
}

/// Bones whose motions agree this closely move as one segment: rotation between them (degrees)
/// and [`SEGMENT_MM`]. Well above the rigid stage's error on bones that truly move together (the
/// fibula lies within 0.5° of the tibia on the real knee pairs), well below a joint's motion.
pub const SEGMENT_DEGREES: f64 = 2.0;
/// Distance between two bones' motions at each bone's centroid (mm) below which they can move
/// as one segment (with [`SEGMENT_DEGREES`]).
pub const SEGMENT_MM: f64 = 1.0;
/// Most a segment's distances are stretched by its size ([`reach_scale`]) where the limit is
/// not chosen per pair (`posereg bend`; `init.reach` chooses among several, [`BoneDistances`]).
pub const MAX_REACH: f64 = 2.0;

/// How much farther than it is a segment's soft tissue "feels": distances to a bone are scaled
/// by ∛(V_largest / V_segment), V_segment the total volume of the bones in the bone's segment
/// and V_largest the largest segment's, clamped to 1..`limit`.
/// A small bone moving on its own (the patella, a ninth of the femur's volume) then pulls less
/// of the tissue around it; with plain distances it drags the anterior thigh through its
/// rotation on the project's phantom (half phantom 60° / 90°: 0.84 / 1.45 mm with the limit 2,
/// 1.50 / 2.56 mm without scaling). Where the truth lets tissue follow the nearest bone
/// whatever its size (the real knee bent by the independent generator) the scaling costs
/// accuracy instead: limit 3 → 2 → none, 2 mm 45° 2.04 → 1.97 → 1.05 mm. Which holds depends
/// on the joint and the scan, so the initialisation tries several limits and keeps the limit
/// where its initialised image's correlation with the target peaks (crate::init::reach). A small
/// bone moving with a large one (the fibula with the tibia) reaches as far as the large one:
/// scaled as a bone of its own, it left the tissue around it to the femur (the knee at 90°:
/// 37 mm off there in the initial field, 8 mm as the segment).
pub fn reach_scale(volume: f64, largest: f64, limit: f64) -> f32 {
    (largest / volume.max(1.0))
        .cbrt()
        .clamp(1.0, limit.max(1.0)) as f32
}

/// A grid sampling every k-th voxel of `grid` per axis, k chosen for about 2.5 mm spacing.
pub fn skinning_grid(grid: &Grid) -> Grid {
    let spacing = grid.spacing();
    grid.every_along(std::array::from_fn(|a| {
        ((SKIN_SPACING_MM / spacing[a]).round() as usize).max(1)
    }))
}

/// For each bone, the first bone of the segment it moves in: bones whose `motions` agree within
/// [`SEGMENT_DEGREES`] and [`SEGMENT_MM`] (at both bones' centroids), joined transitively. The
/// motions are those of the blend being made: a series blends the step between two poses, so
/// there bones join when they moved together during that step.
pub fn segments(motions: &[Affine], centroids: &[Vector3<f64>]) -> Vec<usize> {
    let n = motions.len();
    let moved = |m: &Affine, c: &Vector3<f64>| (m * c.push(1.0)).xyz();
    let apart = |i: usize, j: usize, c: &Vector3<f64>| {
        (moved(&motions[i], c) - moved(&motions[j], c)).norm()
    };
    let together: Vec<Vec<bool>> = (0..n)
        .map(|i| {
            (0..n)
                .map(|j| {
                    crate::joints::joint::degrees_between(&motions[i], &motions[j])
                        < SEGMENT_DEGREES
                        && apart(i, j, &centroids[i]).max(apart(i, j, &centroids[j])) < SEGMENT_MM
                })
                .collect()
        })
        .collect();
    let mut segment: Vec<usize> = (0..n).collect();
    // Each bone takes the lowest segment of any bone it moves with, until nothing changes (a
    // handful of bones: a few passes).
    let mut changed = true;
    while changed {
        changed = false;
        for i in 0..n {
            for j in 0..n {
                if segment[j] < segment[i] && together[i][j] {
                    segment[i] = segment[j];
                    changed = true;
                }
            }
        }
    }
    segment
}

/// Each bone's [`reach_scale`] up to `limit` from its segment's total volume, given each bone's
/// `segment` and `volumes`.
fn segment_reach(segment: &[usize], volumes: &[f64], limit: f64) -> Vec<f32> {
    let total = |s: usize| -> f64 {
        (0..segment.len())
            .filter(|&j| segment[j] == s)
            .map(|j| volumes[j])
            .sum()
    };
    let largest = segment.iter().map(|&s| total(s)).fold(1.0, f64::max);
    segment
        .iter()
        .map(|&s| reach_scale(total(s), largest, limit))
        .collect()
}

/// The distances to each bone on the skinning grid and how the bones group into segments:
/// what the weights are made of, for any reach limit ([`BoneDistances::weights`]).
pub struct BoneDistances<B: Backend> {
    /// The skinning grid.
    pub grid: Grid,
    /// Bone label codes, in weight order.
    pub bones: Vec<u16>,
    /// bones.len() distances (mm) per voxel of the grid.
    distances: B::Buffer<f32>,
    /// Each bone's segment.
    segment: Vec<usize>,
    /// Each bone's volume (source voxels).
    volumes: Vec<f64>,
}

impl<B: Backend> BoneDistances<B> {
    /// Skinning weights falling off as d⁻ᵖᵒʷᵉʳ ([`SHEPARD_POWER`] for the initialisation),
    /// distances stretched by [`reach_scale`] up to `limit`.
    pub fn weights(&self, backend: &B, power: u32, limit: f64) -> Result<SkinningWeights<B>> {
        let reach = segment_reach(&self.segment, &self.volumes, limit);
        let params = SkinWeightsParams::new(&self.grid, &reach, power);
        Ok(SkinningWeights {
            data: backend.skin_weights(&params, &self.distances)?,
            grid: self.grid.clone(),
            bones: self.bones.clone(),
        })
    }
}

/// The distances to `bones` of the source `labels` (codes, where the backend computes) on the
/// skinning grid. With the bones' `motions`, bones moving together form a segment and reach
/// as one ([`reach_scale`]); without, each bone reaches as itself.
pub fn distances<B: Backend>(
    backend: &B,
    labels: &DeviceImage<B>,
    bones: &[u16],
    motions: Option<&[Affine]>,
) -> Result<BoneDistances<B>> {
    crate::abi::check_bone_count(bones.len())?;
    let grid = skinning_grid(&labels.grid);
    // The skinning grid's voxels are source voxels: nearest-voxel sampling picks their labels.
    let on_grid = ResampleParams::new(&labels.grid, &grid, 0.0, Interpolation::Nearest);
    let still = backend.zeros("zero displacement", 3 * grid.len())?;
    let sampled = DeviceImage {
        data: backend.resample(&on_grid, &labels.data, &still)?,
        grid: grid.clone(),
    };
    let (mut volumes, mut centroids) = (Vec::new(), Vec::new());
    for &bone in bones {
        let on_skinning_grid = regions::label_index(backend, &sampled, &[bone])?;
        if regions::moments(backend, &on_skinning_grid, 0.5)?.voxels == 0 {
            return Err(Error::InvalidInput(format!(
                "bone label {bone} has no voxels on the skinning grid"
            )));
        }
        let on_source_grid = regions::label_index(backend, labels, &[bone])?;
        let moments = regions::moments(backend, &on_source_grid, 0.5)?;
        volumes.push(moments.voxels as f64);
        centroids.push(moments.centroid);
    }
    let segment = match motions {
        Some(motions) if motions.len() == bones.len() => segments(motions, &centroids),
        Some(motions) => {
            return Err(Error::InvalidInput(format!(
                "{} motions for {} bones to skin",
                motions.len(),
                bones.len()
            )))
        }
        None => (0..bones.len()).collect(),
    };
    let index = regions::label_index(backend, &sampled, bones)?;
    Ok(BoneDistances {
        distances: regions::distance_maps(backend, &index, bones.len())?,
        grid,
        bones: bones.to_vec(),
        segment,
        volumes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Translation3};

    fn motion(degrees: f64, shift: [f64; 3]) -> Affine {
        let r = Rotation3::from_axis_angle(&Vector3::x_axis(), degrees.to_radians());
        (Translation3::new(shift[0], shift[1], shift[2]) * r).to_homogeneous()
    }

    #[test]
    fn bones_moving_together_form_one_segment() {
        // The tibia, fibula and fifth bone lie near the x axis, which the motions turn about:
        // between them only the angles tell.
        let centroids = [
            Vector3::new(0.0, 0.0, 40.0),  // femur
            Vector3::new(0.0, 0.0, -5.0),  // tibia
            Vector3::new(0.0, 30.0, 10.0), // patella
            Vector3::new(30.0, 0.0, -5.0), // fibula
            Vector3::new(-30.0, 0.0, -5.0),
        ];
        let motions = [
            motion(0.0, [0.0; 3]),
            motion(45.0, [0.0, -5.0, 0.0]),
            motion(30.0, [0.0; 3]),
            motion(46.2, [0.0, -5.0, 0.0]), // 1.2° from the tibia
            motion(47.4, [0.0, -5.0, 0.0]), // 2.4° from the tibia, 1.2° from the fibula
        ];
        assert_eq!(segments(&motions, &centroids), vec![0, 1, 2, 1, 1]);
        // 1.2 mm apart: not one segment.
        let mut shifted = motions;
        shifted[3] = motion(45.0, [0.0, -3.8, 0.0]);
        shifted[4] = motion(60.0, [0.0, -5.0, 0.0]);
        assert_eq!(segments(&shifted, &centroids), vec![0, 1, 2, 3, 4]);
    }

    #[test]
    fn a_segment_reaches_by_its_whole_size() {
        assert_eq!(reach_scale(1000.0, 1000.0, 2.0), 1.0);
        assert_eq!(reach_scale(1.0, 1000.0, 2.0), 2.0);
        assert_eq!(reach_scale(1.0, 1000.0, 1.5), 1.5);
        assert!((reach_scale(500.0, 1000.0, 2.0) - 2f32.cbrt()).abs() < 1e-6);
        // Femur 1000, tibia 700 and fibula 100 together (800), patella 100.
        let reach = segment_reach(&[0, 1, 2, 1], &[1000.0, 700.0, 100.0, 100.0], 2.0);
        let want = [1.0, 1.25f32.cbrt(), 2.0, 1.25f32.cbrt()];
        for (got, want) in reach.iter().zip(want) {
            assert!((got - want).abs() < 1e-6, "{reach:?}");
        }
    }

    #[test]
    fn segments_join_through_several_passes() {
        // 0 joins 2 and 2 joins 1, but 0 and 1 are 2.4° apart: the chain 0 – 2 – 1 is one
        // segment, which the first pass (1 before 2) cannot see.
        let centroids = [Vector3::new(10.0, 0.0, 0.0); 3];
        let motions = [
            motion(45.0, [0.0; 3]),
            motion(47.4, [0.0; 3]),
            motion(46.2, [0.0; 3]),
        ];
        assert_eq!(segments(&motions, &centroids), vec![0, 0, 0]);
    }
}
