//! Where the initialisation puts the bones in the target, and the pins the adaptive stage
//! holds on their surfaces: the bone each target voxel's source point lies in (computed where
//! the backend computes; the boundaries of that map come back as a list for the pins).

use crate::abi::{BoneLookupParams, SurfaceParams};
use crate::backend::reduce::flagged;
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use crate::init::articulated::{InitialImages, PairImages};
use nalgebra::Vector3;

/// Up to `per_bone` points on the surface in the target of each of `bones` bones: boundary
/// voxels of the region whose source point the initial field puts in that bone (`bone_map`,
/// [`initial_bones`]), spread by farthest-point sampling. The boundaries are found where the
/// backend computes and only they come back (as a list), not the map.
pub fn bone_pins<B: Backend>(
    backend: &B,
    bone_map: &DeviceImage<B>,
    bones: usize,
    per_bone: usize,
) -> Result<Vec<Vector3<f64>>> {
    let grid = &bone_map.grid;
    let surface = backend.region_surface(&SurfaceParams::new(grid), &bone_map.data)?;
    let (voxels, bone_of) = flagged(backend, &surface, grid.len())?;
    let mut pins = Vec::new();
    for index in 1..=bones {
        let points: Vec<Vector3<f64>> = voxels
            .iter()
            .zip(&bone_of)
            .filter(|&(_, &bone)| bone == index as f32)
            .map(|(&v, _)| grid.world_of(v as usize))
            .collect();
        pins.extend(spread(&points, per_bone));
    }
    Ok(pins)
}

/// 1 + the position among `bones` of the bone in which the initial field puts each target
/// voxel's source point, 0 for soft tissue: where the initialisation moves a bone rigidly.
pub fn initial_bones<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    initial: &InitialImages<B>,
    bones: &[u16],
) -> Result<DeviceImage<B>> {
    let grid = &initial.field.grid;
    let lookup = BoneLookupParams::new(&pair.labels.grid, grid, bones, f32::MAX)?;
    let data = backend.bone_at_source(
        &lookup,
        &initial.field.data,
        &initial.residual.data,
        &pair.labels.data,
    )?;
    Ok(DeviceImage {
        data,
        grid: grid.clone(),
    })
}

/// Up to `count` of `points`, each farthest from those chosen before it, from the first.
fn spread(points: &[Vector3<f64>], count: usize) -> Vec<Vector3<f64>> {
    let Some(first) = points.first() else {
        return Vec::new();
    };
    let mut chosen = vec![*first];
    let mut nearest: Vec<f64> = points.iter().map(|p| (p - first).norm()).collect();
    while chosen.len() < count {
        let (k, far) = nearest
            .iter()
            .enumerate()
            .fold((0, 0.0), |b, (k, &v)| if v > b.1 { (k, v) } else { b });
        if far < 1e-6 {
            break;
        }
        chosen.push(points[k]);
        for (m, p) in points.iter().enumerate() {
            nearest[m] = nearest[m].min((p - points[k]).norm());
        }
    }
    chosen
}
