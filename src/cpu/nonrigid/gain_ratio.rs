//! CPU twin of shaders/nonrigid/gain_ratio.wgsl.

use crate::abi::GainParams;
use rayon::prelude::*;

/// Fills `gain` with the clamped ratio product / energy, 1 where energy ≤ the floor.
pub fn gain_ratio(params: &GainParams, product: &[f32], energy: &[f32], gain: &mut [f32]) {
    let (floor, most) = (params.floor, params.most);
    gain.par_iter_mut().enumerate().for_each(|(v, g)| {
        let e = energy[v];
        *g = if e > floor {
            (product[v] / e).clamp(1.0 / most, most)
        } else {
            1.0
        };
    });
}
