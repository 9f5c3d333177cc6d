//! Where the initialisation puts the bones in the target, and the pins the adaptive stage
//! holds on their surfaces: the bone each target voxel's source point lies in (computed where
//! the backend computes; the map comes back once for the pins).

use crate::abi::BoneLookupParams;
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use crate::init::articulated::{InitialImages, PairImages};
use crate::volume::Grid;
use nalgebra::Vector3;

/// Up to `per_bone` points on the surface in the target of each of `bones` bones: boundary
/// voxels of the region whose source point the initial field puts in that bone (`bone_map`,
/// [`initial_bones`]), spread by farthest-point sampling. The map (one value per voxel) comes
/// back for the boundaries and the sampling.
pub fn bone_pins<B: Backend>(
    backend: &B,
    bone_map: &DeviceImage<B>,
    bones: usize,
    per_bone: usize,
) -> Result<Vec<Vector3<f64>>> {
    let grid = &bone_map.grid;
    let bone_of = backend.download_one(&bone_map.data)?;
    let mut pins = Vec::new();
    for index in 1..=bones {
        let inside: Vec<bool> = bone_of.iter().map(|&b| b == index as f32).collect();
        pins.extend(spread(&surface_points(grid, &inside), per_bone));
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

/// World positions of the voxels of `inside` with a 6-neighbour outside it.
fn surface_points(grid: &Grid, inside: &[bool]) -> Vec<Vector3<f64>> {
    let d = grid.dims;
    (0..grid.len())
        .filter(|&n| {
            if !inside[n] {
                return false;
            }
            let (i, j, k) = (n % d[0], (n / d[0]) % d[1], n / (d[0] * d[1]));
            let neighbours = [
                (i > 0).then(|| n - 1),
                (i + 1 < d[0]).then(|| n + 1),
                (j > 0).then(|| n - d[0]),
                (j + 1 < d[1]).then(|| n + d[0]),
                (k > 0).then(|| n - d[0] * d[1]),
                (k + 1 < d[2]).then(|| n + d[0] * d[1]),
            ];
            neighbours.iter().any(|m| m.is_some_and(|m| !inside[m]))
        })
        .map(|n| grid.world_of(n))
        .collect()
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
