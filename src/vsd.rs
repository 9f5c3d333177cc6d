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

use crate::abi::{Blending, BoneBlend};
use crate::backend::Backend;
use crate::error::Result;
use crate::fold_repair::{repair_folds, FoldRepair};
use crate::skinning::SkinningWeights;
use crate::volume::{Affine, Field, Grid, Image, Labels, Volume};

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
pub fn initial_field<B: Backend>(
    backend: &B,
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
    let residual = Image::from_data(target.clone(), out.chunks_exact(4).map(|c| c[3]).collect())?;
    let mut field = Image::from_data(target.clone(), field)?;
    let repair = repair_folds(backend, &mut field, &residual, labels, &weights.bones)?;
    Ok(InitialField {
        field,
        residual,
        repair,
    })
}
