//! CPU twin of shaders/field/invert_field.wgsl: the inverse of a displacement field by Newton's
//! method per voxel.

use crate::abi::InvertParams;
use crate::cpu::common::{det3, dims3, solve3};
use crate::sample::{
    affine_row, array_from, blend_corners, corner_indices, inside_source, linear_row,
};
use glam::Vec3;
use rayon::prelude::*;

/// Keep in sync with shaders/field/invert_field.wgsl.
const NEWTON_STEPS: u32 = 40;
const HALVINGS: u32 = 12;
const CONVERGED_MM: f32 = 1e-4;
const SINGULAR: f32 = 1e-6;

/// u at a field index (clamped into the field's grid) and its index-space gradient rows.
struct Local {
    u: Vec3,
    g: [Vec3; 3],
}

/// The field's three components as volumes (the shader reads one at a time).
struct Components<'a> {
    params: &'a InvertParams,
    each: [Vec<f32>; 3],
}

impl Components<'_> {
    #[inline(always)]
    fn local(&self, q: Vec3) -> Local {
        let d = dims3(self.params.field_dims);
        let top = Vec3::new(d[0] as f32, d[1] as f32, d[2] as f32) - Vec3::ONE;
        let qc = q.clamp(Vec3::ZERO, top).to_array();
        // The shader samples each component in turn; their corners are the same voxels.
        let (at, t) = corner_indices(qc, d);
        let s: [[f32; 4]; 3] = array_from(|c| {
            let component = &self.each[c];
            blend_corners(array_from(|k| component[at[k] as usize]), t)
        });
        Local {
            u: Vec3::new(s[0][0], s[1][0], s[2][0]),
            g: s.map(|v| Vec3::new(v[1], v[2], v[3])),
        }
    }

    fn to_index(&self, v: Vec3) -> Vec3 {
        let m = self.params.mm_to_index;
        let v = v.to_array();
        Vec3::new(
            linear_row(m[0], v),
            linear_row(m[1], v),
            linear_row(m[2], v),
        )
    }

    fn mm_length(&self, f: Vec3) -> f32 {
        let l = self.params.index_to_mm;
        let f = f.to_array();
        Vec3::new(
            linear_row(l[0], f),
            linear_row(l[1], f),
            linear_row(l[2], f),
        )
        .length()
    }

    fn jacobian_row(&self, r: usize, unit: Vec3, at: &Local) -> Vec3 {
        let m = self.params.mm_to_index[r];
        unit + m[0] * at.g[0] + m[1] * at.g[1] + m[2] * at.g[2]
    }

    /// w and the residual (−1: no preimage) at output voxel p.
    #[inline(always)]
    fn invert_at(&self, p: [f32; 3]) -> (Vec3, f32) {
        let t = self.params.index_to_field;
        let qy = Vec3::new(
            affine_row(t[0], p),
            affine_row(t[1], p),
            affine_row(t[2], p),
        );
        let mut q = qy - self.to_index(self.local(qy).u);
        let mut at = self.local(q);
        let mut f = q + self.to_index(at.u) - qy;
        let mut size = self.mm_length(f);
        let mut step = 0;
        while step < NEWTON_STEPS && size >= CONVERGED_MM {
            let r0 = self.jacobian_row(0, Vec3::X, &at);
            let r1 = self.jacobian_row(1, Vec3::Y, &at);
            let r2 = self.jacobian_row(2, Vec3::Z, &at);
            let det = det3(r0, r1, r2);
            let delta = match det.abs() > SINGULAR {
                true => solve3(r0, r1, r2, det, -f),
                false => -f,
            };
            let mut shrunk = false;
            let mut scale = 1.0;
            let mut h = 0;
            while h < HALVINGS && !shrunk {
                let qn = q + scale * delta;
                let an = self.local(qn);
                let fq = qn + self.to_index(an.u) - qy;
                let sn = self.mm_length(fq);
                if sn < size {
                    (q, at, f, size) = (qn, an, fq, sn);
                    shrunk = true;
                }
                scale *= 0.5;
                h += 1;
            }
            if !shrunk {
                break;
            }
            step += 1;
        }
        let inside = inside_source(q.to_array(), dims3(self.params.field_dims));
        (-at.u, if inside { size } else { -1.0 })
    }
}

/// Fills `out` (3 floats per output voxel) with the inverse of `field` (3 floats per field
/// voxel) and `residual` (1 float per output voxel) with |z + u(z) − y| in mm, −1 where y has
/// no preimage inside the field's grid.
pub fn invert_field(params: &InvertParams, field: &[f32], out: &mut [f32], residual: &mut [f32]) {
    let components = Components {
        params,
        each: std::array::from_fn(|c| field.par_chunks_exact(3).map(|u| u[c]).collect()),
    };
    let [nx, ny, _] = dims3(params.out_dims);
    // By rows, not slices: Newton takes many more steps where the field folds or compresses
    // sharply, and a slice across such a region kept a core idle.
    out.par_chunks_mut(3 * nx as usize)
        .zip(residual.par_chunks_mut(nx as usize))
        .enumerate()
        .for_each(|(row, (out, res))| {
            let (j, k) = (row as u32 % ny, row as u32 / ny);
            invert_row(&components, [j, k], out, res)
        });
}

/// Output row (j, k) of [`invert_field`]; also compiled for AVX2 (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn invert_row(components: &Components, [j, k]: [u32; 2], out: &mut [f32], res: &mut [f32]) {
    for (i, res) in res.iter_mut().enumerate() {
        let (w, r) = components.invert_at([i as f32, j as f32, k as f32]);
        out[3 * i..3 * i + 3].copy_from_slice(&w.to_array());
        *res = r;
    }
}
