//! CPU twin of shaders/skin_blend.wgsl.

use super::common::{affine_row, det3, solve3};
use crate::abi::{SkinBlendParams, MAX_SKIN_BONES};
use crate::sample::{axis_corners, corner_index, nearest};
use glam::{Vec3, Vec4};
use rayon::prelude::*;

/// A voxel whose blend lands within this of its target point needs no more steps (mm): a
/// thousandth of a millimetre, far below any registration's error; the steps converge
/// linearly (the weights' derivative is left out), and 1e-4 took a quarter longer (half phantom
/// 60°: 2.04 against 1.62 s).
const CONVERGED_MM: f32 = 1e-3;
/// The miss before any candidate is chosen (the shader's literal).
const NOT_CHOSEN: f32 = 3.4e38;

#[derive(Clone, Copy, Default)]
struct Blend {
    point: Vec3,
    r0: Vec3,
    r1: Vec3,
    r2: Vec3,
}

fn row(r: [f32; 4]) -> Vec3 {
    Vec3::new(r[0], r[1], r[2])
}

#[inline(always)]
fn bone_at(params: &SkinBlendParams, bone_of_voxel: &[f32], x: Vec3) -> u32 {
    let bones = params.blend[0];
    let n = [
        params.label_dims[0],
        params.label_dims[1],
        params.label_dims[2],
    ];
    let xa = x.to_array();
    let q: [f32; 3] = std::array::from_fn(|r| affine_row(params.world_to_label[r], xa));
    let b = nearest(bone_of_voxel, q, n, 0.0) as u32;
    if b > 0 {
        b - 1
    } else {
        bones
    }
}

/// The weights at the eight corners of one weight-grid cell (per corner, one lane per bone),
/// kept from one blend to the next: a voxel's steps mostly stay in one cell, so the 8 × bones
/// lookups need not be repeated. A corner's bones lie together in the weight grid, so each
/// corner is one copy; and the bones' weights are interpolated lane by lane, each lane with the
/// shader's operations in its order. The weights are those the lookups give, so the blend is
/// the same; the shader looks them up each time.
struct CellWeights {
    /// Flat index of the cell's first corner; `u32::MAX` before any.
    first: u32,
    /// Per corner (x fastest), the weight of each bone (lanes past the bone count unused).
    corners: [[f32; MAX_SKIN_BONES]; 8],
}

impl CellWeights {
    fn new() -> Self {
        CellWeights {
            first: u32::MAX,
            corners: [[0.0; MAX_SKIN_BONES]; 8],
        }
    }

    /// Every bone's weight at fraction `t` of the cell, in lanes (the shader's trilinear
    /// blend of each bone's eight corners, lane by lane).
    #[inline(always)]
    fn at(&self, t: Vec3) -> [f32; MAX_SKIN_BONES] {
        let [v000, v100, v010, v110, v001, v101, v011, v111] = &self.corners;
        let lerp = |a: &[f32; MAX_SKIN_BONES], b: &[f32; MAX_SKIN_BONES], t: f32| {
            std::array::from_fn(|j| (1.0 - t) * a[j] + t * b[j])
        };
        let c00 = lerp(v000, v100, t.x);
        let c10 = lerp(v010, v110, t.x);
        let c01 = lerp(v001, v101, t.x);
        let c11 = lerp(v011, v111, t.x);
        let c0 = lerp(&c00, &c10, t.y);
        let c1 = lerp(&c01, &c11, t.y);
        lerp(&c0, &c1, t.z)
    }
}

#[inline(always)]
fn blend(
    params: &SkinBlendParams,
    weight: &[f32],
    bone_of_voxel: &[f32],
    x: Vec3,
    cell: &mut CellWeights,
) -> Blend {
    let n = [
        params.weight_dims[0],
        params.weight_dims[1],
        params.weight_dims[2],
    ];
    let bones = params.blend[0];
    let xa = x.to_array();
    let inside = bone_at(params, bone_of_voxel, x);
    if inside < bones {
        let m = [0, 1, 2].map(|r| params.forward[(3 * inside + r) as usize]);
        return Blend {
            point: Vec3::new(
                affine_row(m[0], xa),
                affine_row(m[1], xa),
                affine_row(m[2], xa),
            ),
            r0: row(m[0]),
            r1: row(m[1]),
            r2: row(m[2]),
        };
    }
    let s = Vec3::from_array(std::array::from_fn(|r| {
        affine_row(params.world_to_weight[r], xa)
    }));
    let q = s.clamp(
        Vec3::ZERO,
        Vec3::new(n[0] as f32 - 1.0, n[1] as f32 - 1.0, n[2] as f32 - 1.0),
    );
    // q is inside the grid, so the corners are ⌊q⌋ and ⌊q⌋ + 1 clamped to it.
    let axes: [([u32; 2], f32); 3] = std::array::from_fn(|a| axis_corners(q[a], n[a]));
    let ends = axes.map(|(ends, _)| ends);
    let t = Vec3::from_array(axes.map(|(_, t)| t));
    let mut b = Blend {
        point: Vec3::ZERO,
        r0: Vec3::ZERO,
        r1: Vec3::ZERO,
        r2: Vec3::ZERO,
    };
    let dual_quaternion = params.blend[2] == 1;
    let mut real = Vec4::ZERO;
    let mut dual = Vec4::ZERO;
    let first = corner_index(0, ends, n);
    if first != cell.first {
        cell.first = first;
        let bones = bones as usize;
        for (c, lanes) in cell.corners.iter_mut().enumerate() {
            let at = (corner_index(c, ends, n) as usize) * bones;
            // A whole lane-width copy where the grid reaches that far (the lanes past the
            // bone count then hold the next voxels' weights, unused): a fixed-size copy, where
            // one of `bones` floats is a call to memmove.
            *lanes = match weight.get(at..at + MAX_SKIN_BONES) {
                Some(window) => window.try_into().expect("MAX_SKIN_BONES floats"),
                None => std::array::from_fn(|j| weight.get(at + j).copied().unwrap_or(0.0)),
            };
        }
    }
    let weights = cell.at(t);
    for j in 0..bones {
        let w = weights[j as usize];
        if dual_quaternion {
            real += w * Vec4::from_array(params.dual[(2 * j) as usize]);
            dual += w * Vec4::from_array(params.dual[(2 * j + 1) as usize]);
        } else {
            let m = [0, 1, 2].map(|r| params.forward[(3 * j + r) as usize]);
            b.point += w * Vec3::new(
                affine_row(m[0], xa),
                affine_row(m[1], xa),
                affine_row(m[2], xa),
            );
            b.r0 += w * row(m[0]);
            b.r1 += w * row(m[1]);
            b.r2 += w * row(m[2]);
        }
    }
    if dual_quaternion {
        return dual_quaternion_motion(real, dual, x);
    }
    b
}

/// The rigid motion of the blended dual quaternion (real, dual), applied to x: normalised by
/// the real part's length, rotation from the real part, translation 2 (dual · conj(real)).
#[inline(always)]
fn dual_quaternion_motion(real_sum: Vec4, dual_sum: Vec4, x: Vec3) -> Blend {
    let norm = real_sum.length();
    let r = real_sum / norm;
    let d = dual_sum / norm;
    let t = 2.0 * (r.w * d.truncate() - d.w * r.truncate() + r.truncate().cross(d.truncate()));
    let r0 = Vec3::new(
        1.0 - 2.0 * (r.y * r.y + r.z * r.z),
        2.0 * (r.x * r.y - r.z * r.w),
        2.0 * (r.x * r.z + r.y * r.w),
    );
    let r1 = Vec3::new(
        2.0 * (r.x * r.y + r.z * r.w),
        1.0 - 2.0 * (r.x * r.x + r.z * r.z),
        2.0 * (r.y * r.z - r.x * r.w),
    );
    let r2 = Vec3::new(
        2.0 * (r.x * r.z - r.y * r.w),
        2.0 * (r.y * r.z + r.x * r.w),
        1.0 - 2.0 * (r.x * r.x + r.y * r.y),
    );
    Blend {
        point: Vec3::new(r0.dot(x), r1.dot(x), r2.dot(x)) + t,
        r0,
        r1,
        r2,
    }
}

/// Fills `field` (3 floats per target voxel: u) and `residual` (1 float per target voxel);
/// `bone_of_voxel` holds 1 + the bone index (0 for soft tissue) per source label voxel.
pub fn skin_blend(
    params: &SkinBlendParams,
    weight: &[f32],
    bone_of_voxel: &[f32],
    field: &mut [f32],
    residual: &mut [f32],
) {
    let [nx, ny, _, _] = params.dims;
    // By rows, not slices: a slice across the joint takes many times longer than one away
    // from it, and the last such slice kept one core idle (half phantom 60°: 36 ms).
    field
        .par_chunks_mut(3 * nx as usize)
        .zip(residual.par_chunks_mut(nx as usize))
        .enumerate()
        .for_each(|(row, (field, residual))| {
            let (j, k) = (row as u32 % ny, row as u32 / ny);
            blend_row(params, weight, bone_of_voxel, [j, k], field, residual)
        });
}

/// Target row (j, k) of [`skin_blend`]'s field and residual; also compiled for AVX2
/// (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn blend_row(
    params: &SkinBlendParams,
    weight: &[f32],
    bone_of_voxel: &[f32],
    [j, k]: [u32; 2],
    field: &mut [f32],
    residual: &mut [f32],
) {
    let mut cell = CellWeights::new();
    for (i, residual) in residual.iter_mut().enumerate() {
        let v = [i as f32, j as f32, k as f32];
        let p = Vec3::from_array(std::array::from_fn(|r| {
            affine_row(params.target_to_world[r], v)
        }));
        let (x, err) = preimage(params, weight, bone_of_voxel, p, &mut cell);
        field[3 * i..3 * i + 3].copy_from_slice(&[x.x - p.x, x.y - p.y, x.z - p.z]);
        *residual = err;
    }
}

/// The point x whose blend lands on target point p, and the miss |blend(x) − p| (mm): from
/// the best of each bone's inverse motion of p ([`best_candidate`]), damped steps with the
/// blended linear part as the Jacobian.
#[inline(always)]
fn preimage(
    params: &SkinBlendParams,
    weight: &[f32],
    bone_of_voxel: &[f32],
    p: Vec3,
    cell: &mut CellWeights,
) -> (Vec3, f32) {
    let (mut x, mut err, mut b) = best_candidate(params, weight, bone_of_voxel, p, cell);
    let mut it = 0;
    while it < params.blend[1] && err > CONVERGED_MM {
        it += 1;
        let e = b.point - p;
        let det = det3(b.r0, b.r1, b.r2);
        let step = if det.abs() > 1e-6 {
            solve3(b.r0, b.r1, b.r2, det, e)
        } else {
            e
        };
        let mut t = 1.0f32;
        let mut moved = false;
        for _ in 0..5 {
            let trial = x - t * step;
            let at = blend(params, weight, bone_of_voxel, trial, cell);
            let miss = (at.point - p).length();
            if miss < err {
                x = trial;
                err = miss;
                b = at;
                moved = true;
                break;
            }
            t *= 0.5;
        }
        if !moved {
            break;
        }
    }
    (x, err)
}

/// Of each bone's inverse motion of p, the one whose blend lands nearest to p: that point, its
/// miss (mm) and its blend, which the first step reuses. Where no miss is finite, p itself, the
/// miss [`NOT_CHOSEN`] and the blend at p.
#[inline(always)]
fn best_candidate(
    params: &SkinBlendParams,
    weight: &[f32],
    bone_of_voxel: &[f32],
    p: Vec3,
    cell: &mut CellWeights,
) -> (Vec3, f32, Blend) {
    let pa = p.to_array();
    let mut x = p;
    let mut best = NOT_CHOSEN;
    let mut b = Blend::default();
    for j in 0..params.blend[0] {
        let inv = |r: u32| params.inverse[(3 * j + r) as usize];
        let candidate = Vec3::new(
            affine_row(inv(0), pa),
            affine_row(inv(1), pa),
            affine_row(inv(2), pa),
        );
        let at = blend(params, weight, bone_of_voxel, candidate, cell);
        let miss = (at.point - p).length();
        if miss < best {
            best = miss;
            x = candidate;
            b = at;
        }
    }
    if best == NOT_CHOSEN {
        b = blend(params, weight, bone_of_voxel, x, cell);
    }
    (x, best, b)
}
