//! CPU twin of shaders/dense/norm_max.wgsl. The shader keeps the largest length as it goes; the
//! twin keeps the largest squared length in [`LANES`] running maxima, so that the loop runs in
//! vector lanes, and takes one square root per chunk. Both give the same bits: a correctly
//! rounded square root is monotonic, so the root of the largest square is the largest root, and
//! a maximum does not depend on the order it is taken in (the squares are never −0).

use crate::abi::dense::NormParams;
use rayon::prelude::*;

/// Running maxima kept side by side: eight, the f32 lanes of an AVX2 register.
const LANES: usize = 8;

/// Fills `maxima` (one per chunk) with the largest vector length of each chunk of `field`.
pub fn norm_max(params: &NormParams, field: &[f32], maxima: &mut [f32]) {
    let (vectors, per_chunk) = (params.vectors as usize, params.per_chunk as usize);
    maxima.par_iter_mut().enumerate().for_each(|(c, largest)| {
        let chunk = &field[3 * c * per_chunk..3 * ((c + 1) * per_chunk).min(vectors)];
        *largest = largest_square(chunk).sqrt();
    });
}

/// The largest x² + y² + z² of `vectors` (3 floats each), 0 for none. Also compiled for AVX2
/// (crate::cpu's notes).
#[multiversion::multiversion(targets("x86_64+avx2"))]
fn largest_square(vectors: &[f32]) -> f32 {
    let mut lanes = [0.0f32; LANES];
    let blocks = vectors.chunks_exact(3 * LANES);
    let rest = blocks.remainder();
    for block in blocks {
        for (l, u) in block.chunks_exact(3).enumerate() {
            lanes[l] = lanes[l].max(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        }
    }
    for u in rest.chunks_exact(3) {
        lanes[0] = lanes[0].max(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    }
    lanes.into_iter().fold(0.0, f32::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_root_of_the_largest_square_is_the_shaders_largest_root() {
        // Chunks of 37 vectors, the last short, lengths spread over many scales, some zero.
        let vectors: usize = 1000;
        let field: Vec<f32> = (0..3 * vectors)
            .map(|i| match i % 11 {
                0 => 0.0,
                r => ((i as f32) * 0.731).sin() * 10f32.powi(r as i32 - 5),
            })
            .collect();
        let params = NormParams {
            vectors: vectors as u32,
            per_chunk: 37,
            chunks: vectors.div_ceil(37) as u32,
            pad: 0,
        };
        let mut maxima = vec![0.0; params.chunks as usize];
        norm_max(&params, &field, &mut maxima);
        for (c, got) in maxima.iter().enumerate() {
            let shader = (c * 37..((c + 1) * 37).min(vectors))
                .map(|v| {
                    let u = &field[3 * v..3 * v + 3];
                    (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt()
                })
                .fold(0.0f32, f32::max);
            assert_eq!(got.to_bits(), shader.to_bits(), "chunk {c}");
        }
    }
}
