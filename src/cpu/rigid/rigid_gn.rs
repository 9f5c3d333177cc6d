//! CPU twin of shaders/rigid/rigid_gn.wgsl: the same per-column sums, one slice per rayon task.

use crate::abi::{RigidParams, RIGID_SUMS as SUMS};
use crate::backend::rigid::BoneImages;
use crate::cpu::common::{affine_row, linear_row, voxel_index};
use crate::sample::{inside_source, trilinear_with_gradient};
use glam::Vec3;
use rayon::prelude::*;

/// Fills `partial` (29 per (x, z) column) from the source, the mask and the target.
pub fn rigid_gn(params: &RigidParams, images: &BoneImages<[f32]>, partial: &mut [f32]) {
    let BoneImages {
        source,
        mask,
        target,
    } = *images;
    let [nx, ny, nz, _] = params.dims;
    let tdims = [
        params.target_dims[0],
        params.target_dims[1],
        params.target_dims[2],
    ];
    partial
        .par_chunks_mut(nx as usize * SUMS)
        .enumerate()
        .for_each(|(z, out)| {
            let z = z as u32;
            for x in 0..nx {
                let mut acc = [0.0f32; SUMS];
                for y in 0..ny {
                    let i = voxel_index(x, y, z, [nx, ny, nz]) as usize;
                    if mask[i] < 0.5 {
                        continue;
                    }
                    let p = [x as f32, y as f32, z as f32];
                    let q: [f32; 3] =
                        std::array::from_fn(|r| affine_row(params.to_target_index[r], p));
                    if !inside_source(q, tdims) {
                        continue;
                    }
                    let vg = trilinear_with_gradient(target, q, tdims);
                    let r = vg[0] - source[i];
                    let gi = [vg[1], vg[2], vg[3]];
                    let g = Vec3::from_array(std::array::from_fn(|k| {
                        linear_row(params.gradient_to_world[k], gi)
                    }));
                    let d = Vec3::from_array(std::array::from_fn(|k| {
                        affine_row(params.to_centred_world[k], p)
                    }));
                    let w = d.cross(g);
                    let jac = [w.x, w.y, w.z, g.x, g.y, g.z];
                    let mut s = 0;
                    for a in 0..6 {
                        for b in a..6 {
                            acc[s] += jac[a] * jac[b];
                            s += 1;
                        }
                    }
                    for a in 0..6 {
                        acc[21 + a] += jac[a] * r;
                    }
                    acc[27] += r * r;
                    acc[28] += 1.0;
                }
                out[x as usize * SUMS..(x as usize + 1) * SUMS].copy_from_slice(&acc);
            }
        });
}
