//! Which target voxels count as evidence, and which a field takes inside the source: what the
//! non-rigid stages weigh their image terms by.

use crate::abi::{Interpolation, ResampleParams, ThresholdParams};
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use crate::volume::{Grid, Labels};

/// The target mask on `field`'s grid (1 where the target's voxels count, 0 elsewhere: all of
/// the target without one) and where `field` takes them inside the `source` grid, where the
/// backend computes; and the mask's share of the target grid.
pub fn mask_and_coverage<B: Backend>(
    backend: &B,
    source: &Grid,
    field: &DeviceImage<B>,
    target_mask: Option<&Labels>,
) -> Result<(DeviceImage<B>, DeviceImage<B>, f64)> {
    let grid = &field.grid;
    let (mask, mask_share) = match target_mask {
        Some(mask) => {
            crate::backend::check_grids(&mask.grid, grid)?;
            let mask: Vec<f32> = mask.data.iter().map(|&m| (m > 0) as u8 as f32).collect();
            let inside = mask.iter().filter(|&&m| m > 0.0).count().max(1);
            let share = inside as f64 / mask.len() as f64;
            (backend.upload("target mask", mask)?, share)
        }
        None => (everywhere(backend, grid)?, 1.0),
    };
    let mask = DeviceImage {
        data: mask,
        grid: grid.clone(),
    };
    let params = ResampleParams::new(source, grid, 0.0, Interpolation::Linear);
    let coverage = DeviceImage {
        data: backend.coverage(&params, &field.data, &mask.data)?,
        grid: grid.clone(),
    };
    Ok((mask, coverage, mask_share))
}

/// 1 at every voxel of `grid`, made where the backend computes rather than uploaded: the
/// voxels of a zero image at or below 0, none of them held (mark_at_most).
fn everywhere<B: Backend>(backend: &B, grid: &Grid) -> Result<B::Buffer<f32>> {
    let zeros = backend.zeros("zeros", grid.len())?;
    backend.mark_at_most(&ThresholdParams::new(grid, 0.0), &zeros, &zeros)
}
