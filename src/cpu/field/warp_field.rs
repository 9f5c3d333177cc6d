//! CPU twin of shaders/field/warp_field.wgsl.

use crate::abi::RbfGradParams;
use crate::cpu::lattice_warp::LatticeTaps;
use rayon::prelude::*;

/// Fills `out` (3 floats per voxel) with the warp interpolated from `lattice`.
pub fn warp_field(params: &RbfGradParams, lattice: &[f32], out: &mut [f32]) {
    let [nx, ny, _, _] = params.dims;
    let taps = LatticeTaps::new(params);
    out.par_chunks_mut(3 * (nx * ny) as usize)
        .enumerate()
        .for_each(|(zl, slice)| {
            let k = zl as u32;
            for j in 0..ny {
                let row = taps.row(params, lattice, j, k);
                for i in 0..nx {
                    let o = 3 * (i + nx * j) as usize;
                    slice[o..o + 3].copy_from_slice(&row.warp_at(&taps, i).to_array());
                }
            }
        });
}
