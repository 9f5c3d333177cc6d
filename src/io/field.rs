//! Displacement fields on disk, in the ITK/ANTs convention: a NIfTI vector image
//! (dims x, y, z, 1, 3; intent code 1007 NIFTI_INTENT_VECTOR; float32) whose vector at target
//! point p is d, in LPS millimetres, such that p + d is the matching source point. SimpleITK
//! (`DisplacementFieldTransform`), antsApplyTransforms and greedy apply such files directly.
//! In memory posereg keeps fields in RAS mm; the conversion is a sign flip of x and y.

use super::nifti::{read_raw, write_image, DataType, RawImage};
use crate::error::{Error, Result};
use crate::volume::{Field, Grid, Image};
use std::path::Path;

/// NIFTI_INTENT_VECTOR: what ITK, ANTs and posereg write.
pub const INTENT_VECTOR: i32 = 1007;
/// NIFTI_INTENT_DISPVECT: a displacement vector, as some tools write.
pub const INTENT_DISPVECT: i32 = 1006;

/// RAS ↔ LPS for a displacement vector (its own inverse).
pub fn flip_ras_lps(v: [f32; 3]) -> [f32; 3] {
    [-v[0], -v[1], v[2]]
}

/// Saves a RAS field as an ITK displacement field (LPS vectors), float32.
pub fn save_field(path: &Path, field: &Field) -> Result<()> {
    let g = &field.grid;
    let n = g.len();
    // Components are the slowest axis on disk: all x components, then all y, then all z.
    let mut planar = vec![0.0f32; 3 * n];
    for (i, v) in field.data.iter().enumerate() {
        let lps = flip_ras_lps(*v);
        for c in 0..3 {
            planar[c * n + i] = lps[c];
        }
    }
    let dims = [g.dims[0], g.dims[1], g.dims[2], 1, 3];
    write_image(path, &dims, &g.affine, &planar, DataType::F32, |h| {
        h.intent_code = INTENT_VECTOR as i16;
    })
}

/// Loads an ITK displacement field (dims x, y, z, 1, 3; vector intent) into RAS vectors.
pub fn load_field(path: &Path) -> Result<Field> {
    field_from_raw(path, read_raw(path)?)
}

/// A displacement field from its raw read: vector intent, dims (x, y, z, 1, 3), finite vectors.
pub fn field_from_raw(path: &Path, raw: RawImage) -> Result<Field> {
    let intent = raw.info.header.intent_code;
    if intent != INTENT_VECTOR && intent != INTENT_DISPVECT {
        return Err(Error::bad_file(
            path,
            format!(
                "is not a displacement field: its intent code is {intent}, not 1007 \
                 (NIFTI_INTENT_VECTOR, what ITK, ANTs and posereg write) or 1006 (DISPVECT)"
            ),
        ));
    }
    let dims = &raw.info.header.dims;
    if dims.len() != 5 || dims[3] != 1 || dims[4] != 3 {
        return Err(Error::bad_file(
            path,
            format!("is not a 3-D displacement field: dims {dims:?}, expected [x, y, z, 1, 3]"),
        ));
    }
    let grid = Grid::new([dims[0], dims[1], dims[2]], raw.info.affine)
        .map_err(|e| Error::bad_file(path, e.to_string()))?;
    let n = grid.len();
    if let Some(i) = raw.data.iter().position(|v| !v.is_finite()) {
        return Err(Error::bad_file(
            path,
            format!(
                "displacement field has NaN or Inf vectors, the first at voxel {}",
                i % n
            ),
        ));
    }
    let data = (0..n)
        .map(|i| flip_ras_lps([raw.data[i], raw.data[n + i], raw.data[2 * n + i]]))
        .collect();
    Ok(Image { grid, data })
}
