//! A knee phantom in any pose, with exact ground truth.
//!
//! The anatomy ([`anatomy`]) is a continuous function of world position in the straight (0°)
//! pose. A bent phantom is that anatomy sampled through the flexion map ([`flexion`]): for each
//! voxel p of the bent image, q(p) is the straight-pose point that flexion carries to p, the
//! image is the anatomy at q(p), and the truth field is u(p) = q(p) − p — the same convention as
//! a registration's output field (target point → source point).

pub mod acquisition;
pub mod anatomy;
pub mod flexion;
pub mod shapes;
mod unfold;

use crate::backend::Backend;
use crate::cpu::CpuBackend;
use crate::error::{Error, Result};
use crate::images::fold_repair::host_determinant;
use crate::io::transform::{BoneTransform, BoneTransforms};
use crate::volume::{Affine, Field, Grid, Image, Labels, Volume};
use acquisition::{add_rician_noise, BiasField};
use anatomy::BONES;
use flexion::Flexion;
use glam::Vec3;
use rayon::prelude::*;
use unfold::{unfold, Held};

/// Grid presets covering the same field of view (170 × 320 × 307 mm).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PhantomSize {
    /// 34 × 64 × 64 at 5 × 5 × 4.8 mm: the scale at which the paper registered (§4).
    Quarter,
    /// 48 × 96 × 96 (≈3.5 × 3.3 × 3.2 mm): tests.
    Small,
    /// 68 × 128 × 128 at 2.5 × 2.5 × 2.4 mm.
    Half,
    /// 136 × 256 × 256 at 1.25 × 1.25 × 1.2 mm: the paper's scans.
    Paper,
}

/// Field of view (mm) along x (medio-lateral), y (antero-posterior), z (long axis).
const FIELD_OF_VIEW: [f64; 3] = [170.0, 320.0, 307.2];
/// Centre of the field of view: behind the knee, so the bent shank stays in view longer.
const FOV_CENTRE: [f64; 3] = [0.0, -40.0, 0.0];

impl PhantomSize {
    /// Voxels along each axis.
    pub fn dims(self) -> [usize; 3] {
        match self {
            PhantomSize::Quarter => [34, 64, 64],
            PhantomSize::Small => [48, 96, 96],
            PhantomSize::Half => [68, 128, 128],
            PhantomSize::Paper => [136, 256, 256],
        }
    }

    /// The RAS-aligned grid, centred on the field of view.
    pub fn grid(self) -> Grid {
        let dims = self.dims();
        let mut affine = Affine::identity();
        for a in 0..3 {
            let spacing = FIELD_OF_VIEW[a] / dims[a] as f64;
            affine[(a, a)] = spacing;
            affine[(a, 3)] = FOV_CENTRE[a] - spacing * (dims[a] - 1) as f64 / 2.0;
        }
        Grid::new(dims, affine).expect("preset grids are valid")
    }
}

/// What phantom to make.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PhantomSpec {
    /// Grid preset.
    pub size: PhantomSize,
    /// Knee flexion in degrees, 0 to 120.
    pub flexion_degrees: f64,
    /// Relative amplitude of the bias field (0 off).
    pub bias: f32,
    /// Noise σ relative to the brightest tissue (fat ≈ 1000); 0 off.
    pub noise: f32,
    /// Seed for the bias field and the noise.
    pub seed: u64,
}

impl Default for PhantomSpec {
    fn default() -> Self {
        PhantomSpec {
            size: PhantomSize::Paper,
            flexion_degrees: 0.0,
            bias: 0.15,
            noise: 0.02,
            seed: 1,
        }
    }
}

/// A phantom image with its labels and the truth relating it to the straight pose.
pub struct Phantom {
    /// T1-like intensities.
    pub image: Volume,
    /// Label codes (0 outside, 1 soft tissue, 2 femur, 3 tibia, 4 patella, 5 fibula).
    pub labels: Labels,
    /// Target (this image) point → straight-pose point, RAS mm.
    pub truth_field: Field,
    /// Each bone's rigid motion, straight → this pose, plus the flexion axis.
    pub truth: BoneTransforms,
}

/// Brightest tissue intensity; the noise level is relative to it.
const INTENSITY_SCALE: f32 = 1000.0;

/// Builds a phantom. It is made on the host (the CPU backend computes the Jacobians of its truth
/// field's unfolding), so that a spec gives the same bytes whatever device the caller uses.
pub fn generate(spec: &PhantomSpec) -> Result<Phantom> {
    if !(0.0..=120.0).contains(&spec.flexion_degrees) {
        return Err(Error::InvalidInput(format!(
            "flexion {}° is outside 0..120",
            spec.flexion_degrees
        )));
    }
    let bias_ok = (0.0..1.0).contains(&spec.bias);
    // Noise is relative to the brightest tissue: beyond 1 it swamps every edge, and large
    // values overflow f32 (1e20 gave an image of Inf).
    let noise_ok = (0.0..=1.0).contains(&spec.noise);
    if !(bias_ok && noise_ok) {
        return Err(Error::InvalidInput(format!(
            "bias must be in [0, 1) and noise in [0, 1] (got {}, {})",
            spec.bias, spec.noise
        )));
    }
    let grid = spec.size.grid();
    let flexion = Flexion::knee(spec.flexion_degrees);
    let straight: Vec<Vec3> = if spec.flexion_degrees == 0.0 {
        (0..grid.len())
            .into_par_iter()
            .map(|n| world_of(&grid, n))
            .collect()
    } else {
        unfolded(&CpuBackend, &grid, flexion.straight_points(&grid))?
    };
    // Anti-alias over about one voxel.
    let edge = grid.spacing().iter().cloned().fold(0.0, f64::max) as f32;
    let bias = BiasField::new(spec.bias, spec.seed);
    let (mut image, labels): (Vec<f32>, Vec<u16>) = straight
        .par_iter()
        .enumerate()
        .map(|(n, q)| {
            let (v, label) = anatomy::sample(*q, edge);
            (v * bias.gain(world_of(&grid, n)), label)
        })
        .unzip();
    let slice = grid.dims[0] * grid.dims[1];
    add_rician_noise(&mut image, slice, spec.noise * INTENSITY_SCALE, spec.seed);
    let truth_field = straight
        .par_iter()
        .enumerate()
        .map(|(n, q)| (*q - world_of(&grid, n)).to_array())
        .collect();
    let mut truth = BoneTransforms::new(
        BONES
            .iter()
            .map(|(code, name)| BoneTransform::new(*code, name, &flexion.bone_matrix(*code)))
            .collect(),
    );
    truth.extra.insert(
        "flexion_axis".into(),
        serde_json::json!({
            "point": flexion.axis_point.to_array(),
            "direction": flexion.axis_direction.to_array(),
            "degrees": spec.flexion_degrees,
            "patella_share": flexion::PATELLA_SHARE,
        }),
    );
    truth.extra.insert(
        "phantom".into(),
        serde_json::to_value(spec).unwrap_or_default(),
    );
    Ok(Phantom {
        image: Image {
            grid: grid.clone(),
            data: image,
        },
        labels: Image {
            grid: grid.clone(),
            data: labels,
        },
        truth_field: Image {
            grid,
            data: truth_field,
        },
        truth,
    })
}

/// The flow sampled at voxel centres folds by finite differences where it turns faster than a
/// grid resolves: behind the femoral condyles, where the shank's plateau sweeps the tissue
/// between it and the femur into a layer under a millimetre thick (0, 208 and 1231 voxels at
/// 60°, 90° and 120° on the paper grid). There the straight points are pushed apart
/// ([`unfold`]), voxels inside a bone fixed and none pushed into one, so the field the bent
/// image is sampled through has det J > 0.05 at every voxel. The truth stays exact: it is that
/// field. Voxels the push leaves alone keep their points bit for bit.
fn unfolded<B: Backend>(backend: &B, grid: &Grid, straight: Vec<Vec3>) -> Result<Vec<Vec3>> {
    let bone_number = |p: Vec3| {
        let inside = BONES
            .iter()
            .position(|(code, _)| anatomy::bone(*code, p) <= 0.0);
        inside.map_or(0.0, |b| (b + 1) as f32)
    };
    let in_bone = |p: Vec3| bone_number(p) > 0.0;
    let held: Vec<f32> = straight.par_iter().map(|&q| bone_number(q)).collect();
    let displacement = |n: usize, q: Vec3| (q - world_of(grid, n)).to_array();
    let sampled = straight
        .iter()
        .enumerate()
        .map(|(n, q)| displacement(n, *q))
        .collect();
    let mut field = Image::from_data(grid.clone(), sampled)?;
    let det = host_determinant(backend, &field)?;
    let both = Held {
        bones: &held,
        rigid: &held,
    };
    unfold(&mut field, det, both, &|n, u| {
        in_bone(world_of(grid, n) + Vec3::from_array(u))
    });
    Ok(straight
        .into_iter()
        .enumerate()
        .map(|(n, q)| {
            if field.data[n] == displacement(n, q) {
                q
            } else {
                world_of(grid, n) + Vec3::from_array(field.data[n])
            }
        })
        .collect())
}

/// World position of flat voxel index n.
fn world_of(grid: &Grid, n: usize) -> Vec3 {
    let w = grid.world_of(n);
    Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32)
}
