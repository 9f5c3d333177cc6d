//! What the scanner adds: a smooth multiplicative bias field and Rician noise, both seeded.
//! Both are functions of the voxel (the scanner's frame), not of the anatomy, so a bent
//! phantom gets them where it lies in the bore.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

/// A smooth bias field 1 + strength · g(p), |g| ≤ 1, from two seeded plane waves with
/// wavelengths of 250–500 mm (the slow shading of a receive coil).
pub struct BiasField {
    waves: [(Vec3, f32, f32); 2],
    strength: f32,
}

impl BiasField {
    /// A bias field of relative amplitude `strength` (0 turns it off).
    pub fn new(strength: f32, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xB1A5);
        let mut wave = |weight: f32| {
            let dir = Vec3::new(
                rng.random_range(-1.0..1.0f32),
                rng.random_range(-1.0..1.0f32),
                rng.random_range(-1.0..1.0f32),
            )
            .normalize_or(Vec3::Z);
            let wavelength = rng.random_range(250.0..500.0f32);
            let phase = rng.random_range(0.0..std::f32::consts::TAU);
            (dir * (std::f32::consts::TAU / wavelength), phase, weight)
        };
        BiasField {
            waves: [wave(0.6), wave(0.4)],
            strength,
        }
    }

    /// The multiplicative gain at world point p.
    pub fn gain(&self, p: Vec3) -> f32 {
        let g: f32 = self
            .waves
            .iter()
            .map(|(k, phase, w)| w * (k.dot(p) + phase).sin())
            .sum();
        1.0 + self.strength * g
    }
}

/// Replaces each value s by the magnitude |s + n₁ + i n₂| with n₁, n₂ ~ N(0, σ²): the Rician
/// noise of a magnitude MR image. Each slice has its own seeded stream, so the result does not
/// depend on the number of threads.
pub fn add_rician_noise(data: &mut [f32], slice_len: usize, sigma: f32, seed: u64) {
    if sigma <= 0.0 {
        return;
    }
    let normal = Normal::new(0.0f32, sigma).expect("sigma is positive and finite");
    data.par_chunks_mut(slice_len)
        .enumerate()
        .for_each(|(slice, values)| {
            let mut rng =
                ChaCha8Rng::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ slice as u64);
            for v in values {
                let re = *v + normal.sample(&mut rng);
                let im = normal.sample(&mut rng);
                *v = (re * re + im * im).sqrt();
            }
        });
}
