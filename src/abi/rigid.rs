//! The per-bone rigid stage: Gauss-Newton sums and candidate scores.

use super::*;

/// Sums per column of rigid_gn: JᵀJ upper triangle (21), Jᵀr (6), Σr² (1), count (1).
pub const RIGID_SUMS: usize = 29;

/// Sums per column and candidate of rigid_score: Σr², count, ΣS, ΣT, ΣS², ΣT², ΣS·T.
pub const SCORE_SUMS: usize = 7;

/// 12 floats per candidate: rows 0..3 of each matrix (the rigid_score kernel's layout).
pub fn pack_candidates(candidates: &[Affine]) -> Vec<f32> {
    candidates
        .iter()
        .flat_map(|m| (0..3).flat_map(move |r| (0..4).map(move |c| m[(r, c)] as f32)))
        .collect()
}

/// Keep in sync with `RigidParams` in shaders/rigid/rigid_gn.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct RigidParams {
    /// Source nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Target nx, ny, nz, unused.
    pub target_dims: [u32; 4],
    /// Source voxel index → target continuous index under the current motion.
    pub to_target_index: [[f32; 4]; 3],
    /// Source voxel index → moved world point minus the rotation centre.
    pub to_centred_world: [[f32; 4]; 3],
    /// Target index-space gradient → world gradient ((L_t⁻¹)ᵀ).
    pub gradient_to_world: [[f32; 4]; 3],
}

impl RigidParams {
    /// For motion `m` (source world → target world) linearised about `centre` (target world).
    pub fn new(source: &Grid, target: &Grid, m: &Affine, centre: [f64; 3]) -> Self {
        let to_target = target.world_to_voxel_affine() * m * source.affine;
        let mut centred = m * source.affine;
        for r in 0..3 {
            centred[(r, 3)] -= centre[r];
        }
        let lt: nalgebra::Matrix3<f64> = target.affine.fixed_view::<3, 3>(0, 0).into_owned();
        let grad = lt
            .try_inverse()
            .expect("validated grids are invertible")
            .transpose();
        RigidParams {
            dims: dims4(source, 0),
            target_dims: dims4(target, 0),
            to_target_index: rows(&to_target),
            to_centred_world: rows(&centred),
            gradient_to_world: linear_rows(&grad),
        }
    }

    /// Columns of the source (one partial result each): nx · nz.
    pub fn columns(&self) -> usize {
        self.dims[0] as usize * self.dims[2] as usize
    }
}

/// Keep in sync with `ScoreParams` in shaders/rigid/rigid_score.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct ScoreParams {
    /// Source nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Target nx, ny, nz, unused.
    pub target_dims: [u32; 4],
    /// Source voxel index → world.
    pub source_to_world: [[f32; 4]; 3],
    /// World → target continuous index.
    pub world_to_target: [[f32; 4]; 3],
    /// Candidate motions scored.
    pub candidates: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}

impl ScoreParams {
    /// For `candidates` motions of a bone from `source` into `target`.
    pub fn new(source: &Grid, target: &Grid, candidates: usize) -> Self {
        ScoreParams {
            dims: dims4(source, 0),
            target_dims: dims4(target, 0),
            source_to_world: rows(&source.affine),
            world_to_target: rows(&target.world_to_voxel_affine()),
            candidates: candidates as u32,
            pad: [0; 3],
        }
    }

    /// Columns of the source (one partial result per candidate each): nx · nz.
    pub fn columns(&self) -> usize {
        self.dims[0] as usize * self.dims[2] as usize
    }

    /// Candidate motions scored.
    pub fn candidates(&self) -> usize {
        self.candidates as usize
    }
}
