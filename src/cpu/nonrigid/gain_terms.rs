//! CPU twin of shaders/nonrigid/gain_terms.wgsl.

use rayon::prelude::*;

/// Fills `product` with W · T and `energy` with W · W per voxel.
pub fn gain_terms(warped: &[f32], target: &[f32], product: &mut [f32], energy: &mut [f32]) {
    product
        .par_iter_mut()
        .zip(energy.par_iter_mut())
        .enumerate()
        .for_each(|(v, (p, e))| {
            let w = warped[v];
            *p = w * target[v];
            *e = w * w;
        });
}
