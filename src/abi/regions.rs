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
    /// 1 on the first pass: its input is one volume whose values round to the stack index + 1
    /// on each region.
    pub first: u32,
    /// 1 on the last pass (square roots).
    pub last: u32,
}

impl EdtParams {
    /// The x, y and z passes of the distance maps (mm) on `grid` to the regions 1 ..= `volumes`
    /// of a label index map (or, for one volume, of a 0/1 indicator); refuses grids with a
    /// line longer than [`MAX_EDT_LINE`].
    pub fn passes(grid: &Grid, volumes: usize) -> Result<[EdtParams; 3]> {
        if let Some(&longest) = grid.dims.iter().max().filter(|&&n| n > MAX_EDT_LINE) {
            return Err(Error::InvalidInput(format!(
                "distance maps take grids of at most {MAX_EDT_LINE} voxels along an axis, got {longest}"
            )));
        }
        let h = grid.spacing();
        Ok(std::array::from_fn(|axis| EdtParams {
            dims: dims4(grid, 0),
            spacing: [h[0] as f32, h[1] as f32, h[2] as f32, 0.0],
            axis: axis as u32,
            volumes: volumes as u32,
            first: (axis == 0) as u32,
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
