//! Volume skeletal deformation (paper §2): the blend v_a = (Σ_j w_j M_j) v_s of every source
//! point, inverted per target voxel (skin_blend kernel) into the initial displacement field u0
//! on the target grid, target point → source point.

use crate::backend::Backend;
use crate::error::Result;
use crate::skinning::SkinningWeights;
use crate::volume::{Affine, Field, Grid, Image, Volume};

/// Newton-like inversion steps per voxel.
pub const INVERSION_ITERATIONS: u32 = 8;

/// The initial field and how well the blend was inverted.
pub struct InitialField {
    /// u0: target point p → source point p + u0(p), world RAS mm.
    pub field: Field,
    /// |B(p + u0(p)) − p| per target voxel (mm): 0 where the inversion is exact.
    pub residual: Volume,
}

/// Inverts the blend of `motions` (one per weight bone, source → target) on `target`.
pub fn initial_field(
    backend: &dyn Backend,
    weights: &SkinningWeights,
    motions: &[Affine],
    target: &Grid,
) -> Result<InitialField> {
    let out = backend.skin_blend(
        &weights.data,
        &weights.grid,
        target,
        motions,
        INVERSION_ITERATIONS,
    )?;
    let field = out.chunks_exact(4).map(|c| [c[0], c[1], c[2]]).collect();
    let residual = out.chunks_exact(4).map(|c| c[3]).collect();
    Ok(InitialField {
        field: Image::from_data(target.clone(), field)?,
        residual: Image::from_data(target.clone(), residual)?,
    })
}
