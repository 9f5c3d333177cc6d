//! Gaussian pyramids that respect anisotropic spacing: each level halves the axes that are not
//! already much coarser than the finest one (a 0.3 × 0.3 × 1.5 mm scan keeps its 1.5 mm axis
//! until the others catch up), smoothing with the binomial kernel of shaders/sampling/pyramid.wgsl.

use crate::abi::PyramidParams;
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use crate::volume::Grid;

/// Fewest voxels an axis keeps when halved.
const MIN_AXIS_VOXELS: usize = 8;

/// The grid one level coarser and the per-axis factors, or None when no axis can be halved.
/// An axis is halved when its spacing is at most 1.5 × the finest spacing: after the step the
/// spacings are then within a factor of 1.5 of each other wherever the data allows it.
pub fn next_level_grid(grid: &Grid) -> Option<(Grid, [usize; 3])> {
    let spacing = grid.spacing();
    let finest = grid.finest_spacing();
    let factors: [usize; 3] = std::array::from_fn(|a| {
        if spacing[a] <= 1.5 * finest && grid.dims[a] >= 2 * MIN_AXIS_VOXELS {
            2
        } else {
            1
        }
    });
    if factors == [1, 1, 1] {
        return None;
    }
    let dims: [usize; 3] = std::array::from_fn(|a| grid.dims[a] / factors[a]);
    // Coarse voxel i sits at fine index f·i + (f − 1)/2: between the two voxels it averages.
    let mut step = nalgebra::Matrix4::<f64>::identity();
    for a in 0..3 {
        step[(a, a)] = factors[a] as f64;
        step[(a, 3)] = (factors[a] as f64 - 1.0) / 2.0;
    }
    let coarse = Grid::new(dims, grid.affine * step).ok()?;
    Some((coarse, factors))
}

/// `image` one level coarser, or None when no axis can be halved.
fn coarser<B: Backend>(backend: &B, image: &DeviceImage<B>) -> Result<Option<DeviceImage<B>>> {
    let Some((grid, factors)) = next_level_grid(&image.grid) else {
        return Ok(None);
    };
    let params = PyramidParams::new(&image.grid, grid.dims, factors);
    Ok(Some(DeviceImage {
        data: backend.pyramid_level(&params, &image.data)?,
        grid,
    }))
}

/// Levels of `image`, finest first (`image` itself), at most `levels` of them (fewer when the
/// grid runs out). The grids depend only on the first one's, so images on one grid get their
/// levels on the same grids.
pub fn build<B: Backend>(
    backend: &B,
    image: DeviceImage<B>,
    levels: usize,
) -> Result<Vec<DeviceImage<B>>> {
    let mut out = vec![image];
    while out.len() < levels {
        match coarser(backend, out.last().expect("never empty"))? {
            Some(level) => out.push(level),
            None => break,
        }
    }
    Ok(out)
}

/// `image` smoothed and halved until its finest spacing reaches `spacing_mm` (or the grid
/// runs out): Gaussian smoothing at about that scale, on the coarse grid it needs.
pub fn down_to_spacing<B: Backend>(
    backend: &B,
    image: DeviceImage<B>,
    spacing_mm: f64,
) -> Result<DeviceImage<B>> {
    let mut level = image;
    while level.grid.finest_spacing() < spacing_mm {
        match coarser(backend, &level)? {
            Some(next) => level = next,
            None => break,
        }
    }
    Ok(level)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Affine;

    #[test]
    fn anisotropic_axes_wait_for_the_others() {
        let mut a = Affine::identity();
        a[(0, 0)] = 0.3125;
        a[(1, 1)] = 0.3125;
        a[(2, 2)] = 1.5;
        let g = Grid::new([512, 512, 80], a).unwrap();
        let (g1, f1) = next_level_grid(&g).unwrap();
        assert_eq!(f1, [2, 2, 1]);
        let (g2, f2) = next_level_grid(&g1).unwrap();
        assert_eq!(f2, [2, 2, 1]);
        let (_, f3) = next_level_grid(&g2).unwrap();
        assert_eq!(f3, [2, 2, 2], "1.5 mm is within 1.5 × 1.25 mm");
        // Voxel 0 of the coarse grid lies midway between fine voxels 0 and 1.
        assert!((g1.voxel_to_world([0.0; 3])[0] - 0.15625).abs() < 1e-12);
    }
}
