//! Regions: distance transforms and moments.

use super::*;

/// Longest line an edt pass takes: the shader keeps a line's envelope in private arrays.
pub const MAX_EDT_LINE: usize = 1024;

/// Keep in sync with `EdtParams` in shaders/regions/edt.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct EdtParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// mm between samples along x, y, z, unused.
    pub spacing: [f32; 4],
    /// The axis of this pass (0 x, 1 y, 2 z).
    pub axis: u32,
    /// Volumes in the stack.
    pub volumes: u32,
    /// Where this pass starts from: [`EDT_FROM_STACK`] (the stack an earlier pass made),
    /// [`EDT_FROM_EACH_REGION`] or [`EDT_FROM_ANY_REGION`] (the first pass, from a label map).
    pub start: u32,
    /// 1 on the last pass (square roots).
    pub last: u32,
}

/// A later edt pass: its input is the stack the pass before made.
pub const EDT_FROM_STACK: u32 = 0;
/// A first edt pass, one volume per region: volume s starts from the voxels whose value rounds
/// to s + 1 (a label index map's region s + 1, or where a 0/1 indicator is at least ½).
pub const EDT_FROM_EACH_REGION: u32 = 1;
/// A first edt pass into one volume, started from every voxel whose value rounds to 1 or more:
/// the distance to the nearest of a label index map's regions.
pub const EDT_FROM_ANY_REGION: u32 = 2;

/// The regions an edt stack measures the distance to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum EdtRegions {
    /// One volume per region 1 ..= n of a label index map (for one region, a 0/1 indicator).
    Each(usize),
    /// One volume: the distance to the nearest region, whichever it is.
    Any,
}

impl EdtParams {
    /// The x, y and z passes of the distance maps (mm) on `grid` to the `regions` of a label
    /// index map; refuses grids with a line longer than [`MAX_EDT_LINE`].
    pub fn passes(grid: &Grid, regions: EdtRegions) -> Result<[EdtParams; 3]> {
        if let Some(&longest) = grid.dims.iter().max().filter(|&&n| n > MAX_EDT_LINE) {
            return Err(Error::InvalidInput(format!(
                "distance maps take grids of at most {MAX_EDT_LINE} voxels along an axis, got {longest}"
            )));
        }
        let h = grid.spacing();
        let volumes = match regions {
            EdtRegions::Each(n) => n,
            EdtRegions::Any => 1,
        };
        Ok(std::array::from_fn(|axis| EdtParams {
            dims: dims4(grid, 0),
            spacing: [h[0] as f32, h[1] as f32, h[2] as f32, 0.0],
            axis: axis as u32,
            volumes: volumes as u32,
            start: match (axis, regions) {
                (0, EdtRegions::Each(_)) => EDT_FROM_EACH_REGION,
                (0, EdtRegions::Any) => EDT_FROM_ANY_REGION,
                _ => EDT_FROM_STACK,
            },
            last: (axis == 2) as u32,
        }))
    }

    /// Values written: volumes × voxels.
    pub fn values(&self) -> usize {
        self.volumes as usize * count(&self.dims)
    }

    /// Lines along the other two axes (each a workgroup dimension).
    pub fn lines(&self) -> [usize; 2] {
        let d = self.dims.map(|n| n as usize);
        match self.axis {
            0 => [d[1], d[2]],
            1 => [d[0], d[2]],
            _ => [d[0], d[1]],
        }
    }
}

/// Keep in sync with `MomentsParams` in shaders/regions/moments.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct MomentsParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Voxels, voxels per chunk ([`STATS_CHUNK`]), chunks, unused.
    pub chunks: [u32; 4],
    /// Value at or above which a voxel counts.
    pub threshold: f32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
    /// Voxel index → world (mm).
    pub index_to_world: [[f32; 4]; 3],
}

impl MomentsParams {
    /// For the voxels of a map on `grid` at or above `threshold`.
    pub fn new(grid: &Grid, threshold: f32) -> Self {
        MomentsParams {
            dims: dims4(grid, 0),
            chunks: chunking(grid.len(), STATS_CHUNK, 0),
            threshold,
            pad: [0; 3],
            index_to_world: rows(&grid.affine),
        }
    }

    /// Chunks the kernel writes 4 values for.
    pub fn chunks(&self) -> usize {
        self.chunks[2] as usize
    }
}
