//! CPU twin of shaders/skinning/skin_blend.wgsl.
//!
//! The shader inverts one voxel per invocation; the twin inverts [`LANES`] neighbouring voxels
//! of a row side by side, each quantity held for all of them in one array ([`Lanes`]), so that
//! the arithmetic runs in vector lanes. Each voxel takes the shader's candidates, steps and
//! trials, every operation in the order of the one-voxel twin this replaced (glam's order where
//! that used glam's vectors, as in a quaternion's length), so the outputs are the same bits;
//! only the lookups into the label and weight grids go voxel by voxel.

use crate::abi::{SkinBlendParams, MAX_SKIN_BONES};
use crate::cpu::common::{affine_row, det3, dims3, solve3};
use crate::sample::{array_from, axis_corners, corner_index, nearest};
use glam::Vec3;
use rayon::prelude::*;

/// A voxel whose blend lands within this of its target point needs no more steps (mm): a
/// thousandth of a millimetre, far below any registration's error; the steps converge
/// linearly (the weights' derivative is left out), and 1e-4 took a quarter longer (half phantom
/// 60°: 2.04 against 1.62 s).
const CONVERGED_MM: f32 = 1e-3;
/// The miss before any candidate is chosen (the shader's literal).
const NOT_CHOSEN: f32 = 3.4e38;
/// Trials per step, the step's length halved after each.
const TRIALS: u32 = 5;

/// Voxels inverted side by side: eight, the f32 lanes of an AVX2 register.
const LANES: usize = 8;

/// One quantity for each of [`LANES`] voxels.
type Lanes = [f32; LANES];
/// One flag for each of [`LANES`] voxels.
type Mask = [bool; LANES];

#[inline(always)]
fn lanes(f: impl FnMut(usize) -> f32) -> Lanes {
    array_from(f)
}

#[inline(always)]
fn mask(f: impl FnMut(usize) -> bool) -> Mask {
    array_from(f)
}

/// `a` where `pick`, else `b`, lane by lane.
#[inline(always)]
fn select(pick: &Mask, a: &Lanes, b: &Lanes) -> Lanes {
    lanes(|l| if pick[l] { a[l] } else { b[l] })
}

/// [`LANES`] points or vectors, one array per component.
#[derive(Clone, Copy, Default)]
struct Points([Lanes; 3]);

impl Points {
    #[inline(always)]
    fn at(&self, l: usize) -> Vec3 {
        Vec3::new(self.0[0][l], self.0[1][l], self.0[2][l])
    }

    /// Each lane's point through the 3 × 4 affine `rows` (affine_row's order).
    #[inline(always)]
    fn affine(rows: &[[f32; 4]], p: &Points) -> Points {
        let [x, y, z] = &p.0;
        Points(array_from(|r| {
            let m = rows[r];
            lanes(|l| m[0] * x[l] + m[1] * y[l] + m[2] * z[l] + m[3])
        }))
    }

    #[inline(always)]
    fn minus(&self, other: &Points) -> Points {
        Points(array_from(|a| lanes(|l| self.0[a][l] - other.0[a][l])))
    }

    /// glam's Vec3::length: √((x² + y²) + z²).
    #[inline(always)]
    fn length(&self) -> Lanes {
        let [x, y, z] = &self.0;
        lanes(|l| (x[l] * x[l] + y[l] * y[l] + z[l] * z[l]).sqrt())
    }

    /// glam's Vec3::dot with `other`.
    #[inline(always)]
    fn dot(&self, other: &Points) -> Lanes {
        let ([x, y, z], [u, v, w]) = (&self.0, &other.0);
        lanes(|l| x[l] * u[l] + y[l] * v[l] + z[l] * w[l])
    }

    #[inline(always)]
    fn select(pick: &Mask, a: &Points, b: &Points) -> Points {
        Points(array_from(|c| select(pick, &a.0[c], &b.0[c])))
    }
}

/// The blended motion at [`LANES`] points: where it takes each point, and its linear part's
/// rows.
#[derive(Clone, Copy, Default)]
struct Blend {
    point: Points,
    r: [Points; 3],
}

impl Blend {
    #[inline(always)]
    fn select(pick: &Mask, a: &Blend, b: &Blend) -> Blend {
        Blend {
            point: Points::select(pick, &a.point, &b.point),
            r: array_from(|i| Points::select(pick, &a.r[i], &b.r[i])),
        }
    }

    /// Lane `l`'s linear part, row by row.
    #[inline(always)]
    fn rows(&self, l: usize) -> [Vec3; 3] {
        [self.r[0].at(l), self.r[1].at(l), self.r[2].at(l)]
    }
}

/// What a blend reads.
struct Images<'a> {
    params: &'a SkinBlendParams,
    weight: &'a [f32],
    bone_of_voxel: &'a [f32],
}

/// The bone whose labelled voxel holds each wanted lane's point x (the bone count for soft
/// tissue, and in the lanes not wanted).
#[inline(always)]
fn bones_at(images: &Images, x: &Points, wanted: &Mask) -> [u32; LANES] {
    let params = images.params;
    let bones = params.bones;
    let n = dims3(params.label_dims);
    let q = Points::affine(&params.world_to_label, x);
    let mut inside = [bones; LANES];
    for l in (0..LANES).filter(|&l| wanted[l]) {
        let b = nearest(images.bone_of_voxel, q.at(l).to_array(), n, 0.0) as u32;
        if b > 0 {
            inside[l] = b - 1;
        }
    }
    inside
}

/// Each lane's weight-grid cell, kept from one blend to the next: a voxel's steps mostly stay
/// in one cell, so its 8 × bones lookups need not be repeated. The weights are those the
/// lookups give, so the blend is the same; the shader looks them up each time.
struct Cells {
    /// Per lane, the flat index of the cell's first corner; `u32::MAX` before any.
    first: [u32; LANES],
    /// Per bone and corner (x fastest), the weight in each lane's cell.
    weights: [[Lanes; 8]; MAX_SKIN_BONES],
}

impl Cells {
    fn new() -> Self {
        Cells {
            first: [u32::MAX; LANES],
            weights: [[[0.0; LANES]; 8]; MAX_SKIN_BONES],
        }
    }

    /// Lane `l`'s cell made the one between voxels `ends` of a weight grid of `n` voxels.
    #[inline(always)]
    fn hold(&mut self, images: &Images, l: usize, ends: [[u32; 2]; 3], n: [u32; 3]) {
        let first = corner_index(0, ends, n);
        if first == self.first[l] {
            return;
        }
        self.first[l] = first;
        let bones = images.params.bones as usize;
        for c in 0..8 {
            let at = corner_index(c, ends, n) as usize * bones;
            // MAX_SKIN_BONES values read at once where the grid reaches that far (those past
            // the bone count are the next voxels' weights, unused): one load, not one per bone.
            let corner: [f32; MAX_SKIN_BONES] = match images.weight.get(at..at + MAX_SKIN_BONES) {
                Some(window) => window.try_into().expect("MAX_SKIN_BONES floats"),
                None => array_from(|j| images.weight.get(at + j).copied().unwrap_or(0.0)),
            };
            for (bone, corners) in self.weights[..bones].iter_mut().enumerate() {
                corners[c][l] = corner[bone];
            }
        }
    }

    /// Bone `bone`'s weight at fraction `t` of each lane's cell (the shader's trilinear blend).
    #[inline(always)]
    fn weight(&self, bone: usize, t: &Points) -> Lanes {
        let [v000, v100, v010, v110, v001, v101, v011, v111] = &self.weights[bone];
        let [tx, ty, tz] = &t.0;
        let lerp = |a: &Lanes, b: &Lanes, t: &Lanes| lanes(|l| (1.0 - t[l]) * a[l] + t[l] * b[l]);
        let c00 = lerp(v000, v100, tx);
        let c10 = lerp(v010, v110, tx);
        let c01 = lerp(v001, v101, tx);
        let c11 = lerp(v011, v111, tx);
        let c0 = lerp(&c00, &c10, ty);
        let c1 = lerp(&c01, &c11, ty);
        lerp(&c0, &c1, tz)
    }
}

/// The blend at each lane's point x, for the lanes `wanted` (the others' values are left to
/// chance): inside a bone's label its own motion, elsewhere the bones' motions blended by the
/// weights.
#[inline(always)]
fn blend(images: &Images, x: &Points, wanted: &Mask, cells: &mut Cells) -> Blend {
    let params = images.params;
    let bones = params.bones;
    let n = dims3(params.weight_dims);
    let inside = bones_at(images, x, wanted);
    let s = Points::affine(&params.world_to_weight, x);
    let q = Points(array_from(|a| {
        let top = n[a] as f32 - 1.0;
        lanes(|l| s.0[a][l].max(0.0).min(top))
    }));
    // q is inside the grid, so the corners are ⌊q⌋ and ⌊q⌋ + 1 clamped to it.
    let mut t = Points::default();
    for l in 0..LANES {
        let mut ends = [[0; 2]; 3];
        for a in 0..3 {
            (ends[a], t.0[a][l]) = axis_corners(q.0[a][l], n[a]);
        }
        if wanted[l] && inside[l] == bones {
            cells.hold(images, l, ends, n);
        }
    }
    let mut b = match params.blending == 1 {
        true => dual_quaternion_blend(params, cells, &t, x),
        false => linear_blend(params, cells, &t, x),
    };
    for (l, &bone) in inside.iter().enumerate().filter(|(_, &bone)| bone < bones) {
        rigid_in_lane(params, bone, x.at(l), l, &mut b);
    }
    b
}

/// Lane `l` of `b` made `bone`'s own motion at x.
#[inline(always)]
fn rigid_in_lane(params: &SkinBlendParams, bone: u32, x: Vec3, l: usize, b: &mut Blend) {
    let xa = x.to_array();
    let rows = &params.forward[3 * bone as usize..3 * bone as usize + 3];
    for (r, m) in rows.iter().enumerate() {
        b.point.0[r][l] = affine_row(*m, xa);
        for (lanes, &value) in b.r[r].0.iter_mut().zip(m) {
            lanes[l] = value;
        }
    }
}

/// The bones' affine motions blended by their weights (the paper's blend).
#[inline(always)]
fn linear_blend(params: &SkinBlendParams, cells: &Cells, t: &Points, x: &Points) -> Blend {
    let mut b = Blend::default();
    for j in 0..params.bones as usize {
        let w = cells.weight(j, t);
        let m = &params.forward[3 * j..3 * j + 3];
        let moved = Points::affine(m, x);
        for (r, row) in m.iter().enumerate() {
            b.point.0[r] = lanes(|l| b.point.0[r][l] + w[l] * moved.0[r][l]);
            for (sum, &value) in b.r[r].0.iter_mut().zip(row) {
                *sum = lanes(|l| sum[l] + w[l] * value);
            }
        }
    }
    b
}

/// The bones' dual quaternions blended by their weights, as the rigid motion they make:
/// normalised by the real part's length, rotation from the real part, translation
/// 2 (dual · conj(real)).
#[inline(always)]
fn dual_quaternion_blend(params: &SkinBlendParams, cells: &Cells, t: &Points, x: &Points) -> Blend {
    let mut real = [[0.0f32; LANES]; 4];
    let mut dual = [[0.0f32; LANES]; 4];
    for j in 0..params.bones as usize {
        let w = cells.weight(j, t);
        let (qr, qd) = (params.dual[2 * j], params.dual[2 * j + 1]);
        for c in 0..4 {
            real[c] = lanes(|l| real[c][l] + w[l] * qr[c]);
            dual[c] = lanes(|l| dual[c][l] + w[l] * qd[c]);
        }
    }
    // glam's Vec4::length: √((x² + z²) + (y² + w²)).
    let norm = lanes(|l| {
        let [x, y, z, w] = [real[0][l], real[1][l], real[2][l], real[3][l]];
        ((x * x + z * z) + (y * y + w * w)).sqrt()
    });
    let r: [Lanes; 4] = array_from(|c| lanes(|l| real[c][l] / norm[l]));
    let d: [Lanes; 4] = array_from(|c| lanes(|l| dual[c][l] / norm[l]));
    let [rx, ry, rz, rw] = &r;
    let [dx, dy, dz, dw] = &d;
    // 2 (r.w d − d.w r + r × d), each term glam's Vec3 operation.
    let cross = Points([
        lanes(|l| ry[l] * dz[l] - dy[l] * rz[l]),
        lanes(|l| rz[l] * dx[l] - dz[l] * rx[l]),
        lanes(|l| rx[l] * dy[l] - dx[l] * ry[l]),
    ]);
    let t = Points(array_from(|a| {
        lanes(|l| 2.0 * ((rw[l] * d[a][l] - dw[l] * r[a][l]) + cross.0[a][l]))
    }));
    let r0 = Points([
        lanes(|l| 1.0 - 2.0 * (ry[l] * ry[l] + rz[l] * rz[l])),
        lanes(|l| 2.0 * (rx[l] * ry[l] - rz[l] * rw[l])),
        lanes(|l| 2.0 * (rx[l] * rz[l] + ry[l] * rw[l])),
    ]);
    let r1 = Points([
        lanes(|l| 2.0 * (rx[l] * ry[l] + rz[l] * rw[l])),
        lanes(|l| 1.0 - 2.0 * (rx[l] * rx[l] + rz[l] * rz[l])),
        lanes(|l| 2.0 * (ry[l] * rz[l] - rx[l] * rw[l])),
    ]);
    let r2 = Points([
        lanes(|l| 2.0 * (rx[l] * rz[l] - ry[l] * rw[l])),
        lanes(|l| 2.0 * (ry[l] * rz[l] + rx[l] * rw[l])),
        lanes(|l| 1.0 - 2.0 * (rx[l] * rx[l] + ry[l] * ry[l])),
    ]);
    let turned = [r0.dot(x), r1.dot(x), r2.dot(x)];
    Blend {
        point: Points(array_from(|a| lanes(|l| turned[a][l] + t.0[a][l]))),
        r: [r0, r1, r2],
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
    let images = Images {
        params,
        weight,
        bone_of_voxel,
    };
    // By rows, not slices: a slice across the joint takes many times longer than one away
    // from it, and the last such slice kept one core idle (half phantom 60°: 36 ms).
    field
        .par_chunks_mut(3 * nx as usize)
        .zip(residual.par_chunks_mut(nx as usize))
        .enumerate()
        .for_each(|(row, (field, residual))| {
            let (j, k) = (row as u32 % ny, row as u32 / ny);
            blend_row(&images, [j, k], field, residual)
        });
}

/// Target row (j, k) of [`skin_blend`]'s field and residual, [`LANES`] voxels at a time; also
/// compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn blend_row(images: &Images, [j, k]: [u32; 2], field: &mut [f32], residual: &mut [f32]) {
    let nx = residual.len();
    let mut cells = Cells::new();
    for first in (0..nx).step_by(LANES) {
        // The row's last voxel fills the lanes past its end.
        let i = |l: usize| (first + l).min(nx - 1) as f32;
        let v = Points([lanes(i), [j as f32; LANES], [k as f32; LANES]]);
        let p = Points::affine(&images.params.target_to_world, &v);
        let (x, err) = preimage(images, &p, &mut cells);
        let voxels = first..nx.min(first + LANES);
        for (l, (u, residual)) in field[3 * voxels.start..3 * voxels.end]
            .chunks_exact_mut(3)
            .zip(&mut residual[voxels])
            .enumerate()
        {
            u.copy_from_slice(&(x.at(l) - p.at(l)).to_array());
            *residual = err[l];
        }
    }
}

/// For each lane's target point p, the point x whose blend lands on p and the miss
/// |blend(x) − p| (mm): from the best of each bone's inverse motion of p
/// ([`best_candidate`]), damped steps with the blended linear part as the Jacobian, each tried
/// at lengths 1, ½, … until the miss falls. The lanes step together, each its own steps.
#[inline(always)]
fn preimage(images: &Images, p: &Points, cells: &mut Cells) -> (Points, Lanes) {
    let max_steps = images.params.iterations;
    let (mut x, mut err, mut b) = best_candidate(images, p, cells);
    let mut steps = [0u32; LANES];
    let mut step = Points::default();
    let mut length = [1.0f32; LANES];
    let mut trials = [0u32; LANES];
    let mut active = [true; LANES];
    begin_steps(&mut active, (&mut steps, max_steps), &err, p, &b, &mut step);
    while active.contains(&true) {
        let trial = Points(array_from(|a| {
            lanes(|l| x.0[a][l] - length[l] * step.0[a][l])
        }));
        let at = blend(images, &trial, &active, cells);
        let miss = at.point.minus(p).length();
        let taken = mask(|l| active[l] && miss[l] < err[l]);
        x = Points::select(&taken, &trial, &x);
        err = select(&taken, &miss, &err);
        b = Blend::select(&taken, &at, &b);
        for l in 0..LANES {
            if active[l] && !taken[l] {
                length[l] *= 0.5;
                trials[l] += 1;
                active[l] = trials[l] < TRIALS;
            }
        }
        let mut next = taken;
        begin_steps(&mut next, (&mut steps, max_steps), &err, p, &b, &mut step);
        for l in (0..LANES).filter(|&l| taken[l]) {
            active[l] = next[l];
            (length[l], trials[l]) = (1.0, 0);
        }
    }
    (x, err)
}

/// Begins the next step in each lane of `lanes` unless its `steps` have reached the most
/// allowed or its miss `err` has converged (then clears the lane).
#[inline(always)]
fn begin_steps(
    lanes: &mut Mask,
    (steps, max_steps): (&mut [u32; LANES], u32),
    err: &Lanes,
    p: &Points,
    b: &Blend,
    step: &mut Points,
) {
    for l in 0..LANES {
        let going_on = steps[l] < max_steps && err[l] > CONVERGED_MM;
        lanes[l] &= going_on;
        if !lanes[l] {
            continue;
        }
        steps[l] += 1;
        let [r0, r1, r2] = b.rows(l);
        let e = b.point.at(l) - p.at(l);
        let det = det3(r0, r1, r2);
        let s = if det.abs() > 1e-6 {
            solve3(r0, r1, r2, det, e)
        } else {
            e
        };
        for a in 0..3 {
            step.0[a][l] = s[a];
        }
    }
}

/// Of each bone's inverse motion of each lane's p, the one whose blend lands nearest to p:
/// that point, its miss (mm) and its blend, which the first step reuses. Where no miss is
/// finite, p itself, the miss [`NOT_CHOSEN`] and the blend at p.
#[inline(always)]
fn best_candidate(images: &Images, p: &Points, cells: &mut Cells) -> (Points, Lanes, Blend) {
    let params = images.params;
    let mut x = *p;
    let mut best = [NOT_CHOSEN; LANES];
    let mut b = Blend::default();
    for j in 0..params.bones as usize {
        let candidate = Points::affine(&params.inverse[3 * j..3 * j + 3], p);
        let at = blend(images, &candidate, &[true; LANES], cells);
        let miss = at.point.minus(p).length();
        let better = mask(|l| miss[l] < best[l]);
        best = select(&better, &miss, &best);
        x = Points::select(&better, &candidate, &x);
        b = Blend::select(&better, &at, &b);
    }
    let none = mask(|l| best[l] == NOT_CHOSEN);
    if none.contains(&true) {
        b = Blend::select(&none, &blend(images, &x, &none, cells), &b);
    }
    (x, best, b)
}
