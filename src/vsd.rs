//! Volume skeletal deformation (paper §2): the blend v_a = (Σ_j w_j M_j) v_s of every source
//! point, inverted per target voxel (skin_blend kernel) into the initial displacement field u0
//! on the target grid, target point → source point.
//!
//! Two blends: linear (the paper's; blending matrices shortens the radius of tissue turning
//! with a bone — a point halfway between a still femur and a tibia turned θ moves along the
//! chord, to cos(θ/2) of its radius — the "candy wrapper" collapse that folds tissue at large
//! flexion) and dual-quaternion (Kavan et al. 2008: blended unit dual quaternions are again
//! rigid motions, so tissue between the bones turns by a blended angle about a blended axis
//! and keeps its distance to the joint).

use crate::backend::Backend;
use crate::error::Result;
use crate::skinning::SkinningWeights;
use crate::volume::{Affine, Field, Grid, Image, Labels, Volume};

/// How the bones' rigid motions are blended across soft tissue.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "kebab-case")]
pub enum Blending {
    /// Σ_j w_j M_j (the paper's linear blend skinning).
    #[default]
    Linear,
    /// The normalised blend of the motions' unit dual quaternions.
    DualQuaternion,
}

/// Bone motions (source → target world) and how to blend and invert them.
#[derive(Clone, Debug)]
pub struct BoneBlend {
    /// One rigid motion per weight bone.
    pub motions: Vec<Affine>,
    /// Linear or dual-quaternion.
    pub blending: Blending,
    /// Newton-like inversion steps per voxel.
    pub iterations: u32,
}

/// Newton-like inversion steps per voxel.
pub const INVERSION_ITERATIONS: u32 = 30;

/// The initial field and how well the blend was inverted.
pub struct InitialField {
    /// u0: target point p → source point p + u0(p), world RAS mm.
    pub field: Field,
    /// |B(p + u0(p)) − p| per target voxel (mm): 0 where the inversion is exact.
    pub residual: Volume,
    /// Folds of the blend removed by local smoothing.
    pub repair: FoldRepair,
}

/// Inverts the blend of `motions` (one per weight bone, source → target) on `target`; the
/// source `labels` make each bone exactly rigid up to its labelled surface.
pub fn initial_field(
    backend: &dyn Backend,
    weights: &SkinningWeights,
    labels: &Labels,
    motions: &[Affine],
    blending: Blending,
    target: &Grid,
) -> Result<InitialField> {
    // 1 + the weight index of the bone each source label voxel belongs to; 0 for soft tissue.
    let bone_of_voxel: Vec<f32> = labels
        .data
        .iter()
        .map(|l| {
            weights
                .bones
                .iter()
                .position(|b| b == l)
                .map_or(0.0, |j| (j + 1) as f32)
        })
        .collect();
    let out = backend.skin_blend(
        &weights.data,
        &weights.grid,
        &bone_of_voxel,
        &labels.grid,
        target,
        &BoneBlend {
            motions: motions.to_vec(),
            blending,
            iterations: INVERSION_ITERATIONS,
        },
    )?;
    let field = out.chunks_exact(4).map(|c| [c[0], c[1], c[2]]).collect();
    let residual = out.chunks_exact(4).map(|c| c[3]).collect();
    let mut field = Image::from_data(target.clone(), field)?;
    let repair = repair_folds(backend, &mut field, labels, &weights.bones)?;
    Ok(InitialField {
        field,
        residual: Image::from_data(target.clone(), residual)?,
        repair,
    })
}

/// Jacobian determinant below which a voxel counts as folded (or about to fold) for repair.
const FOLD_THRESHOLD: f32 = 0.05;
/// Most repair rounds.
const REPAIR_ROUNDS: usize = 30;
/// Voxels around each folded voxel that are smoothed with it.
const REPAIR_MARGIN: usize = 2;

/// What [`repair_folds`] did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct FoldRepair {
    /// Voxels with det ≤ 0.05 before repair.
    pub folded_before: usize,
    /// After.
    pub folded_after: usize,
    /// Rounds of local smoothing.
    pub rounds: usize,
}

/// Linear blend skinning can fold where a bone moves farther than its weights' falloff is wide
/// (seen above the patella). This smooths the displacement locally — the voxels with
/// det J ≤ 0.05 and two voxels around them, by 27-neighbour averaging — until the field no
/// longer folds, leaving voxels that map into one of the `bones` of `labels` untouched so bones
/// stay rigid, and never moving a soft-tissue voxel's source point into a bone (that would grow
/// the bone in the initialised source: at 60° the patella by 10%).
pub fn repair_folds(
    backend: &dyn Backend,
    field: &mut Field,
    labels: &Labels,
    bones: &[u16],
) -> Result<FoldRepair> {
    let [nx, ny, nz] = field.grid.dims;
    let rigid = maps_into_bone(field, labels, bones);
    let into_bone = BoneLookup::new(&field.grid, labels, bones);
    let mut report = FoldRepair::default();
    for round in 0..=REPAIR_ROUNDS {
        let det = backend.jacobian(field)?;
        let bad: Vec<usize> = (0..det.data.len())
            .filter(|&n| det.data[n] <= FOLD_THRESHOLD && !rigid[n])
            .collect();
        if round == 0 {
            report.folded_before = bad.len();
        }
        report.folded_after = bad.len();
        if bad.is_empty() || round == REPAIR_ROUNDS {
            break;
        }
        report.rounds = round + 1;
        let mut region = vec![false; det.data.len()];
        for &n in &bad {
            let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
            let (lo, hi) = (
                |c: usize| c.saturating_sub(REPAIR_MARGIN),
                |c: usize, n: usize| (c + REPAIR_MARGIN + 1).min(n),
            );
            for dk in lo(k)..hi(k, nz) {
                for dj in lo(j)..hi(j, ny) {
                    for di in lo(i)..hi(i, nx) {
                        let m = di + nx * (dj + ny * dk);
                        region[m] = !rigid[m];
                    }
                }
            }
        }
        for _ in 0..3 {
            let before = field.data.clone();
            for n in (0..region.len()).filter(|&n| region[n]) {
                let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
                let mut sum = [0.0f32; 3];
                let mut count = 0.0f32;
                for dk in k.saturating_sub(1)..(k + 2).min(nz) {
                    for dj in j.saturating_sub(1)..(j + 2).min(ny) {
                        for di in i.saturating_sub(1)..(i + 2).min(nx) {
                            let v = before[di + nx * (dj + ny * dk)];
                            for c in 0..3 {
                                sum[c] += v[c];
                            }
                            count += 1.0;
                        }
                    }
                }
                let smoothed = sum.map(|s| s / count);
                if !into_bone.at(n, smoothed) {
                    field.data[n] = smoothed;
                }
            }
        }
    }
    Ok(report)
}

/// Target voxels whose source point (p + u) lies in a bone of `labels` (nearest voxel).
pub fn maps_into_bone(field: &Field, labels: &Labels, bones: &[u16]) -> Vec<bool> {
    let lookup = BoneLookup::new(&field.grid, labels, bones);
    (0..field.grid.len())
        .map(|n| lookup.at(n, field.data[n]))
        .collect()
}

/// Whether target voxel n displaced by u lands in one of `bones` of the source `labels`.
struct BoneLookup<'a> {
    target: &'a Grid,
    labels: &'a Labels,
    bones: &'a [u16],
    to_label: crate::volume::Affine,
}

impl<'a> BoneLookup<'a> {
    fn new(target: &'a Grid, labels: &'a Labels, bones: &'a [u16]) -> Self {
        let to_label = labels.grid.world_to_voxel_affine();
        BoneLookup {
            target,
            labels,
            bones,
            to_label,
        }
    }

    fn at(&self, n: usize, u: [f32; 3]) -> bool {
        let w = self.target.world_of(n);
        let q = self.to_label
            * nalgebra::Vector4::new(
                w[0] + u[0] as f64,
                w[1] + u[1] as f64,
                w[2] + u[2] as f64,
                1.0,
            );
        let ijk = [q.x, q.y, q.z].map(|v| v.round());
        let dims = self.labels.grid.dims;
        if (0..3).any(|a| ijk[a] < 0.0 || ijk[a] >= dims[a] as f64) {
            return false;
        }
        let label = self.labels.data[self.labels.grid.index(
            ijk[0] as usize,
            ijk[1] as usize,
            ijk[2] as usize,
        )];
        self.bones.contains(&label)
    }
}
