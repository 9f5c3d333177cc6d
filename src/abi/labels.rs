//! Label maps: codes and lookups of a bone at a point.

use super::*;

/// Keep in sync with `LabelCodes` in shaders/labels.wgsl: the label codes a kernel compares
/// labels with (up to [`MAX_SKIN_BONES`]: one per bone).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LabelCodes {
    /// Codes in the list.
    pub count: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
    /// The codes, 4 per row.
    pub list: [[u32; 4]; 2],
}

impl LabelCodes {
    /// The codes `codes`, in order.
    pub fn new(codes: &[u16]) -> Result<Self> {
        if codes.len() > MAX_SKIN_BONES {
            return Err(Error::InvalidInput(format!(
                "a label lookup takes at most {MAX_SKIN_BONES} codes, got {}",
                codes.len()
            )));
        }
        let mut list = [[0u32; 4]; 2];
        for (c, &code) in codes.iter().enumerate() {
            list[c / 4][c % 4] = code as u32;
        }
        Ok(LabelCodes {
            count: codes.len() as u32,
            pad: [0; 3],
            list,
        })
    }
}

/// Keep in sync with `LabelParams` in shaders/labels/label_index.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct LabelParams {
    /// nx, ny, nz of the label map, unused.
    pub dims: [u32; 4],
    /// The codes whose positions the kernel writes.
    pub codes: LabelCodes,
}

impl LabelParams {
    /// For a label map on `grid`, indexing `codes`.
    pub fn new(grid: &Grid, codes: &[u16]) -> Result<Self> {
        Ok(LabelParams {
            dims: dims4(grid, 0),
            codes: LabelCodes::new(codes)?,
        })
    }

    /// Voxels of the label map.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `SurfaceParams` in shaders/labels/region_surface.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SurfaceParams {
    /// nx, ny, nz of the region map, unused.
    pub dims: [u32; 4],
}

impl SurfaceParams {
    /// For a region map on `grid`.
    pub fn new(grid: &Grid) -> Self {
        SurfaceParams {
            dims: dims4(grid, 0),
        }
    }

    /// Voxels of the region map.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `BoneLookupParams` in shaders/bone_lookup.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct BoneLookupParams {
    /// Target grid → source label grid, nearest voxel, background −1.
    pub geometry: ResampleParams,
    /// The bones' codes.
    pub codes: LabelCodes,
    /// Largest residual (mm) bone_at_source counts.
    pub limit: f32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}

impl BoneLookupParams {
    /// For target voxels on `target` looking up `bones` in a label map on `labels`, counting
    /// voxels whose residual is at most `residual_limit`.
    pub fn new(labels: &Grid, target: &Grid, bones: &[u16], residual_limit: f32) -> Result<Self> {
        Ok(BoneLookupParams {
            geometry: ResampleParams::new(labels, target, -1.0, Interpolation::Nearest),
            codes: LabelCodes::new(bones)?,
            limit: residual_limit,
            pad: [0; 3],
        })
    }

    /// Voxels of the target grid.
    pub fn voxels(&self) -> usize {
        self.geometry.voxels()
    }
}
