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

use crate::abi::{check_bone_count, Blending, BoneBlend, SkinBlendParams};
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use crate::images::fold_repair::{repair_folds, FoldRepair, SourceLabels};
use crate::images::regions;
use crate::init::skinning::SkinningWeights;
use crate::volume::{Affine, Grid};

/// Newton-like inversion steps per voxel.
pub const INVERSION_ITERATIONS: u32 = 30;

/// The initial field and how well the blend was inverted, where the backend computes.
pub struct InitialField<B: Backend> {
    /// u0: target point p → source point p + u0(p), world RAS mm (3 values per voxel).
    pub field: DeviceImage<B>,
    /// |B(p + u0(p)) − p| per target voxel (mm): 0 where the inversion is exact.
    pub residual: DeviceImage<B>,
    /// Folds of the blend removed.
    pub repair: FoldRepair,
}

/// Inverts the blend of `motions` (one per weight bone, source → target) on `target`; the
/// source `labels` make each bone exactly rigid up to its labelled surface.
pub fn initial_field<B: Backend>(
    backend: &B,
    weights: &SkinningWeights<B>,
    labels: &SourceLabels<B>,
    motions: &[Affine],
    blending: Blending,
    target: &Grid,
) -> Result<InitialField<B>> {
    check_bone_count(motions.len())?;
    let grid = &labels.device.grid;
    // 1 + the weight index of the bone each source label voxel belongs to; 0 for soft tissue.
    let bone_of_voxel = regions::label_index(backend, labels.device, &weights.bones)?;
    let blend = BoneBlend {
        motions: motions.to_vec(),
        blending,
        iterations: INVERSION_ITERATIONS,
    };
    let params = SkinBlendParams::new(target, &weights.grid, grid, &blend);
    let (field, residual) = backend.skin_blend(&params, &weights.data, &bone_of_voxel.data)?;
    let field = DeviceImage {
        grid: target.clone(),
        data: field,
    };
    let residual = DeviceImage {
        grid: target.clone(),
        data: residual,
    };
    let (field, repair) = repair_folds(backend, field, &residual, labels, &weights.bones)?;
    Ok(InitialField {
        field,
        residual,
        repair,
    })
}
