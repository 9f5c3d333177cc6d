//! Regions of label maps where the backend computes: a label's indicator, distance maps to
//! regions, and a region's size and centroid. Only the moments' per-chunk sums come back.

use crate::abi::{EdtParams, EdtRegions, LabelParams, MomentsParams};
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use nalgebra::Vector3;

/// How big a region is and where.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Moments {
    /// Voxels in it.
    pub voxels: usize,
    /// Their centroid (world mm); the origin for an empty region.
    pub centroid: Vector3<f64>,
}

/// Per voxel of `labels` (label codes): 1 + the position of its label among `codes`, else 0.
/// With one code, that label's 0/1 indicator.
pub fn label_index<B: Backend>(
    backend: &B,
    labels: &DeviceImage<B>,
    codes: &[u16],
) -> Result<DeviceImage<B>> {
    let params = LabelParams::new(&labels.grid, codes)?;
    Ok(DeviceImage {
        data: backend.label_index(&params, &labels.data)?,
        grid: labels.grid.clone(),
    })
}

/// The voxels of `image` at or above `threshold`: how many, and their centroid.
pub fn moments<B: Backend>(backend: &B, image: &DeviceImage<B>, threshold: f32) -> Result<Moments> {
    let params = MomentsParams::new(&image.grid, threshold);
    let chunks = backend.download_one(&backend.moments(&params, &image.data)?)?;
    let (mut count, mut sum) = (0.0, Vector3::zeros());
    for chunk in chunks.chunks_exact(4) {
        count += chunk[0];
        sum += Vector3::new(chunk[1], chunk[2], chunk[3]);
    }
    Ok(Moments {
        voxels: count as usize,
        centroid: sum / count.max(1.0),
    })
}

/// Exact Euclidean distance maps (mm) on `index`'s grid to each of its regions 1 ..= `volumes`
/// (voxels whose value rounds to the region's number: a label index map, or a 0/1 indicator
/// smoothed to at least ½ for one region), one volume per region, 0 inside.
pub fn distance_maps<B: Backend>(
    backend: &B,
    index: &DeviceImage<B>,
    volumes: usize,
) -> Result<B::Buffer<f32>> {
    distances(backend, index, EdtRegions::Each(volumes))
}

/// The exact Euclidean distance (mm) on `index`'s grid to the nearest of its regions (voxels
/// whose value rounds to 1 or more), 0 inside any: one volume, the smallest of
/// [`distance_maps`]' at each voxel, for a quarter of their memory with four bones (the
/// paper's grid with four bones' maps, 143 MB, is past many devices' largest binding).
pub fn distance_to_nearest<B: Backend>(
    backend: &B,
    index: &DeviceImage<B>,
) -> Result<B::Buffer<f32>> {
    distances(backend, index, EdtRegions::Any)
}

/// The three edt passes to `regions`.
fn distances<B: Backend>(
    backend: &B,
    index: &DeviceImage<B>,
    regions: EdtRegions,
) -> Result<B::Buffer<f32>> {
    let [x, y, z] = EdtParams::passes(&index.grid, regions)?;
    let along_x = backend.edt(&x, &index.data)?;
    let along_y = backend.edt(&y, &along_x)?;
    backend.edt(&z, &along_y)
}
