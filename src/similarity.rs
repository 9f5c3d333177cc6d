//! Local normalised cross-correlation (LNCC) of two images on one grid: in a box window around
//! each voxel, the squared correlation ρ² of the two images' intensities, averaged over the
//! grid. Insensitive to each scan's own gain and offset within a window (coil shading,
//! contrast between days), which a sum of squared differences is not: on the knee pairs bent
//! by the independent generator the SSD of the initialised image ranked the skinning's reach
//! wrongly where LNCC ranked it as the truth does (BENCHMARKS.md).

use crate::abi::{LnccParams, LocalMomentsParams};
use crate::backend::{Backend, DeviceImage};
use crate::error::{Error, Result};

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
    let [x, y, z] = LocalMomentsParams::passes(&fixed.grid, radius);
    let along_x = backend.local_moments(&x, &fixed.data, &moving.data)?;
    let along_y = backend.local_moments(&y, &along_x, &along_x)?;
    let boxed = backend.local_moments(&z, &along_y, &along_y)?;
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
    use crate::volume::{Affine, Grid};

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
