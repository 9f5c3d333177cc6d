//! Which target voxels count as evidence, and which a field takes inside the source: what the
//! non-rigid stages weigh their image terms by.

use crate::abi::{Interpolation, ResampleParams};
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
    let mask: Vec<f32> = match target_mask {
        Some(mask) => {
            crate::backend::check_grids(&mask.grid, grid)?;
            mask.data.iter().map(|&m| (m > 0) as u8 as f32).collect()
        }
        None => vec![1.0; grid.len()],
    };
    let mask_share = mask.iter().filter(|&&m| m > 0.0).count().max(1) as f64 / mask.len() as f64;
    let mask = DeviceImage {
        data: backend.upload("target mask", mask)?,
        grid: grid.clone(),
    };
    let params = ResampleParams::new(source, grid, 0.0, Interpolation::Linear);
    let coverage = DeviceImage {
        data: backend.coverage(&params, &field.data, &mask.data)?,
        grid: grid.clone(),
    };
    Ok((mask, coverage, mask_share))
}
