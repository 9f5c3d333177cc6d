//! Skinning: the blend of bone motions across soft tissue and its weights.

use super::*;

/// How the bones' rigid motions are blended across soft tissue.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
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

/// Refuses bone counts the skinning kernels cannot take.
pub fn check_bone_count(bones: usize) -> Result<()> {
    if bones == 0 || bones > MAX_SKIN_BONES {
        return Err(Error::InvalidInput(format!(
            "skinning takes 1 to {MAX_SKIN_BONES} bones, got {bones}"
        )));
    }
    Ok(())
}

/// Keep in sync with `SkinWeightsParams` in shaders/skinning/skin_weights.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SkinWeightsParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Bones (volumes of the distance stack, weights per voxel).
    pub bones: u32,
    /// Shepard power p (weights ∝ d⁻ᵖ).
    pub power: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 2],
    /// Per bone, the factor its distances are scaled by (skinning::reach_scale), 4 per row.
    pub reach: [[f32; 4]; 2],
}

impl SkinWeightsParams {
    /// Weights on `grid` with Shepard exponent `power`, one bone per entry of `reach` (at most
    /// [`MAX_SKIN_BONES`]).
    pub fn new(grid: &Grid, reach: &[f32], power: u32) -> Self {
        assert!(reach.len() <= MAX_SKIN_BONES, "checked by the caller");
        let mut rows = [[0.0f32; 4]; 2];
        for (j, &r) in reach.iter().enumerate() {
            rows[j / 4][j % 4] = r;
        }
        SkinWeightsParams {
            dims: dims4(grid, 0),
            bones: reach.len() as u32,
            power,
            pad: [0; 2],
            reach: rows,
        }
    }

    /// Weights written: bones per voxel.
    pub fn values(&self) -> usize {
        count(&self.dims) * self.bones as usize
    }
}

/// Most bones a skinning kernel takes (its matrices live in the uniform).
pub const MAX_SKIN_BONES: usize = 8;

/// Keep in sync with `SkinBlendParams` in shaders/skinning/skin_blend.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SkinBlendParams {
    /// Target nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Bones.
    pub bones: u32,
    /// Most iterations of the inversion.
    pub iterations: u32,
    /// Blending: 0 linear, 1 dual quaternion.
    pub blending: u32,
    /// Padding to 16 bytes.
    pub pad: u32,
    /// Weight grid nx, ny, nz, unused.
    pub weight_dims: [u32; 4],
    /// Source label grid nx, ny, nz, unused.
    pub label_dims: [u32; 4],
    /// Target voxel index → world.
    pub target_to_world: [[f32; 4]; 3],
    /// World → weight-grid continuous index.
    pub world_to_weight: [[f32; 4]; 3],
    /// World → source label grid continuous index.
    pub world_to_label: [[f32; 4]; 3],
    /// Three rows of M_j per bone (source → target world).
    pub forward: [[f32; 4]; 3 * MAX_SKIN_BONES],
    /// Three rows of M_j⁻¹ per bone.
    pub inverse: [[f32; 4]; 3 * MAX_SKIN_BONES],
    /// Unit dual quaternion of M_j per bone: real part (x, y, z, w), then dual part.
    pub dual: [[f32; 4]; 2 * MAX_SKIN_BONES],
}

impl SkinBlendParams {
    /// Voxels of the target grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }

    /// For bones moving as `blend` says (at most [`MAX_SKIN_BONES`]), weights on `weights`,
    /// bone labels on `labels`.
    pub fn new(target: &Grid, weights: &Grid, labels: &Grid, blend: &BoneBlend) -> Self {
        let motions = &blend.motions;
        assert!(motions.len() <= MAX_SKIN_BONES, "checked by the caller");
        let mut forward = [[0.0f32; 4]; 3 * MAX_SKIN_BONES];
        let mut inverse = [[0.0f32; 4]; 3 * MAX_SKIN_BONES];
        let mut dual = [[0.0f32; 4]; 2 * MAX_SKIN_BONES];
        for (j, m) in motions.iter().enumerate() {
            let inv = m.try_inverse().unwrap_or_else(Affine::identity);
            forward[3 * j..3 * j + 3].copy_from_slice(&rows(m));
            inverse[3 * j..3 * j + 3].copy_from_slice(&rows(&inv));
            dual[2 * j..2 * j + 2].copy_from_slice(&dual_quaternion(m));
        }
        let blending = match blend.blending {
            Blending::Linear => 0,
            Blending::DualQuaternion => 1,
        };
        SkinBlendParams {
            dims: dims4(target, 0),
            bones: motions.len() as u32,
            iterations: blend.iterations,
            blending,
            pad: 0,
            weight_dims: dims4(weights, 0),
            label_dims: dims4(labels, 0),
            target_to_world: rows(&target.affine),
            world_to_weight: rows(&weights.world_to_voxel_affine()),
            world_to_label: rows(&labels.world_to_voxel_affine()),
            forward,
            inverse,
            dual,
        }
    }
}

/// The unit dual quaternion (real part, dual part; each x, y, z, w) of a rigid motion, real
/// part in the w ≥ 0 hemisphere: every motion is then on the identity's side, so blending with
/// a bone that barely moves (the femur) takes the short way round for turns below 180°.
fn dual_quaternion(m: &Affine) -> [[f32; 4]; 2] {
    let rotation = nalgebra::Rotation3::from_matrix(&m.fixed_view::<3, 3>(0, 0).into_owned());
    let mut real = nalgebra::UnitQuaternion::from_rotation_matrix(&rotation).into_inner();
    if real.w < 0.0 {
        real = -real;
    }
    let t = nalgebra::Quaternion::from_imag(m.fixed_view::<3, 1>(0, 3).into_owned());
    let dual = t * real * 0.5;
    let q = |q: nalgebra::Quaternion<f64>| [q.i as f32, q.j as f32, q.k as f32, q.w as f32];
    [q(real), q(dual)]
}
