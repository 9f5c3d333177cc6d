//! Local normalised cross-correlation (LNCC) of two images on one grid: in a box window around
//! each voxel, the squared correlation ρ² of the two images' intensities, averaged over the
//! grid. Insensitive to each scan's own gain and offset within a window (coil shading,
//! contrast between days), which a sum of squared differences is not: on the knee pairs bent
//! by the independent generator the SSD of the initialised image ranked the skinning's reach
//! wrongly where LNCC ranked it as the truth does (BENCHMARKS.md). Also the adaptive stage's
//! image term: the sum of squared differences or LNCC, per pyramid level ([`Similarity`],
//! [`LnccCost`]).

use crate::abi::{LnccParams, LnccTermsParams, LocalMomentsParams, RbfGradParams};
use crate::backend::{box_sums, Backend, CostImages, DeviceImage};
use crate::error::{Error, Result};
use crate::volume::Grid;
use std::fmt;
use std::str::FromStr;

/// The image term of the adaptive stage's cost.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Similarity {
    /// Sum of squared differences after the non-rigid stage's smooth intensity gain.
    Ssd,
    /// Local normalised cross-correlation: K Σ (1 − ρ²) over windows, K the target's variance.
    Lncc,
}

impl FromStr for Similarity {
    type Err = String;

    fn from_str(text: &str) -> std::result::Result<Self, String> {
        match text {
            "ssd" => Ok(Similarity::Ssd),
            "lncc" => Ok(Similarity::Lncc),
            _ => Err("not a similarity: ssd or lncc".into()),
        }
    }
}

impl fmt::Display for Similarity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Similarity::Ssd => "ssd",
            Similarity::Lncc => "lncc",
        })
    }
}

/// The LNCC image term through a warp, on one grid: K Σ_w c_w (1 − ρ_w²) over the windows w
/// of (2 radius + 1)³ voxels centred on each voxel (c_w the coverage at the centre), and its
/// exact gradient with respect to the warped image (shaders/correlation/lncc_terms.wgsl), brought through
/// the warp as the SSD's is. Five box-sum passes and three kernels; nothing comes back.
pub struct LnccCost {
    passes: [LocalMomentsParams; 3],
    stack: [LocalMomentsParams; 3],
    terms: LnccTermsParams,
}

impl LnccCost {
    /// On `grid`, windows of `radius` voxels, the cost scaled by `scale` (K).
    pub fn new(grid: &Grid, radius: usize, scale: f32) -> Self {
        LnccCost {
            passes: LocalMomentsParams::passes(grid, radius),
            stack: LocalMomentsParams::stack_passes(grid, radius),
            terms: LnccTermsParams::new(grid, radius, scale),
        }
    }

    /// As `Backend::warp_cost`: the gradient (3 floats per voxel) and the cost per row of x, of
    /// the warp `lattice` (`params`).
    pub fn evaluate<B: Backend>(
        &self,
        backend: &B,
        params: &RbfGradParams,
        lattice: &B::Buffer<f32>,
        images: &CostImages<B::Buffer<f32>>,
    ) -> Result<(B::Buffer<f32>, B::Buffer<f32>)> {
        let warped = backend.warp_image(params, lattice, images.moving)?;
        let sums = box_sums(backend, &self.passes, &warped, images.fixed)?;
        let (terms, rows) = backend.lncc_terms(&self.terms, &sums, images.covered)?;
        let summed = box_sums(backend, &self.stack, &terms, &terms)?;
        let gradient =
            backend.lncc_gradient(params, lattice, images.moving, images.fixed, &summed)?;
        Ok((gradient, rows))
    }
}

/// The mean of ρ² over windows of (2 `radius` + 1)³ voxels of `fixed` and `moving` (on one
/// grid), over the voxels where neither window is flat (0 where every window is); only
/// per-chunk sums come back.
pub fn local_correlation<B: Backend>(
    backend: &B,
    fixed: &DeviceImage<B>,
    moving: &DeviceImage<B>,
    radius: usize,
) -> Result<f64> {
    if !fixed.grid.same_as(&moving.grid, 1e-6) {
        return Err(Error::InvalidInput(
            "local correlation of images on different grids".into(),
        ));
    }
    let passes = LocalMomentsParams::passes(&fixed.grid, radius);
    let boxed = box_sums(backend, &passes, &fixed.data, &moving.data)?;
    let chunks =
        backend.download_one(&backend.lncc(&LnccParams::new(&fixed.grid, radius), &boxed)?)?;
    let (total, counted) = chunks.chunks_exact(2).fold((0.0f64, 0.0f64), |(t, n), c| {
        (t + c[0] as f64, n + c[1] as f64)
    });
    Ok(if counted > 0.0 { total / counted } else { 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::CpuBackend;
    use crate::volume::Affine;

    fn image(grid: &Grid, f: impl Fn(f32, f32, f32) -> f32) -> DeviceImage<CpuBackend> {
        let [nx, ny, _] = grid.dims;
        let data = (0..grid.len())
            .map(|n| {
                f(
                    (n % nx) as f32,
                    ((n / nx) % ny) as f32,
                    (n / (nx * ny)) as f32,
                )
            })
            .collect();
        DeviceImage {
            data: std::sync::Arc::new(data),
            grid: grid.clone(),
        }
    }

    fn texture(x: f32, y: f32, z: f32) -> f32 {
        100.0 + 20.0 * (0.9 * x).sin() * (0.7 * y + 0.3 * z).cos() + 5.0 * (1.3 * z).sin()
    }

    #[test]
    fn gain_and_offset_leave_it_at_one_and_a_shift_lowers_it() {
        let grid = Grid::new([17, 13, 11], Affine::identity()).unwrap();
        let fixed = image(&grid, texture);
        let brighter = image(&grid, |x, y, z| 3.0 * texture(x, y, z) - 40.0);
        let shifted = image(&grid, |x, y, z| texture(x + 1.5, y, z));
        let same = local_correlation(&CpuBackend, &fixed, &brighter, 2).unwrap();
        let off = local_correlation(&CpuBackend, &fixed, &shifted, 2).unwrap();
        assert!((same - 1.0).abs() < 1e-3, "{same}");
        assert!(off < same - 0.1, "{off} against {same}");
    }

    #[test]
    fn flat_windows_are_not_counted() {
        let grid = Grid::new([9, 8, 7], Affine::identity()).unwrap();
        let fixed = image(&grid, texture);
        let flat = image(&grid, |_, _, _| 50.0);
        assert_eq!(
            local_correlation(&CpuBackend, &fixed, &flat, 1).unwrap(),
            0.0
        );
    }
}
