//! What `posereg info` tells of an image: its header's facts, where its voxel→world affine came
//! from, its orientation and its voxels' range, as one value that prints as text or as JSON.

use super::{read_raw, AffineSource, Version};
use crate::error::{Error, Result};
use crate::volume::Grid;
use std::fmt;
use std::path::{Path, PathBuf};

/// An image described (the JSON keys are `posereg info --json`'s).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Description {
    /// The file as named.
    pub file: PathBuf,
    /// dim[1..=dim[0]].
    pub dims: Vec<usize>,
    /// The voxel type's name.
    pub datatype: &'static str,
    /// NIfTI-1 or NIfTI-2.
    pub format: Version,
    /// "big-endian" or "little-endian".
    pub byte_order: &'static str,
    /// Where the voxels start.
    pub vox_offset: u64,
    /// The voxel size along each axis (mm), from the affine.
    pub spacing: [f64; 3],
    /// pixdim[1..4] as stored.
    pub pixdim: [f64; 3],
    /// Voxel → world RAS mm, row by row.
    pub affine: [[f64; 4]; 4],
    /// sform, qform or pixdim.
    pub affine_source: AffineSource,
    /// Orientation code in the nibabel sense ("RAS", "LPI", …).
    pub orientation: String,
    /// The finite voxels' lowest and highest values.
    pub range: [f64; 2],
    /// Voxels that are NaN or infinite.
    pub non_finite_voxels: usize,
    /// scl_slope and scl_inter when they apply.
    pub scaling: Option<[f64; 2]>,
    /// The NIfTI intent code.
    pub intent_code: i32,
}

/// Reads `path` (header and voxels) and describes it.
pub fn describe(path: &Path) -> Result<Description> {
    let raw = read_raw(path)?;
    let (header, affine) = (&raw.info.header, &raw.info.affine);
    let dims3 = std::array::from_fn(|i| *header.dims.get(i).unwrap_or(&1));
    let grid = Grid::new(dims3, *affine).map_err(|e| Error::bad_file(path, e.to_string()))?;
    let finite = raw.data.iter().copied().filter(|v| v.is_finite());
    let range = finite.fold([f32::INFINITY, f32::NEG_INFINITY], |[lo, hi], v| {
        [lo.min(v), hi.max(v)]
    });
    // Printed as f32 values in the text, as f64 in JSON (the same numbers nibabel reads).
    let range = range.map(f64::from);
    Ok(Description {
        file: path.to_path_buf(),
        dims: header.dims.clone(),
        datatype: header.datatype.name(),
        format: header.version,
        byte_order: if header.big_endian {
            "big-endian"
        } else {
            "little-endian"
        },
        vox_offset: header.vox_offset,
        spacing: grid.spacing(),
        pixdim: [header.pixdim[1], header.pixdim[2], header.pixdim[3]],
        affine: std::array::from_fn(|r| std::array::from_fn(|c| affine[(r, c)])),
        affine_source: raw.info.affine_source,
        orientation: grid.orientation_code(),
        range,
        non_finite_voxels: raw.data.iter().filter(|v| !v.is_finite()).count(),
        scaling: header.scaling.map(|(slope, inter)| [slope, inter]),
        intent_code: header.intent_code,
    })
}

impl fmt::Display for Description {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let dims: Vec<String> = self.dims.iter().map(|d| d.to_string()).collect();
        let s = self.spacing;
        writeln!(f, "file:        {}", self.file.display())?;
        writeln!(f, "dims:        {}", dims.join(" x "))?;
        let (kind, order) = (self.format.name(), self.byte_order);
        writeln!(f, "datatype:    {} ({kind}, {order})", self.datatype)?;
        writeln!(f, "spacing:     {:.6} x {:.6} x {:.6} mm", s[0], s[1], s[2])?;
        writeln!(f, "orientation: {}", self.orientation)?;
        writeln!(
            f,
            "affine ({:?}, voxel -> world RAS mm):",
            self.affine_source
        )?;
        for r in &self.affine {
            writeln!(
                f,
                "  [{:>12.6} {:>12.6} {:>12.6} {:>12.6}]",
                r[0], r[1], r[2], r[3]
            )?;
        }
        let [lo, hi] = self.range.map(|v| v as f32);
        writeln!(f, "range:       {lo} .. {hi}")?;
        if self.non_finite_voxels > 0 {
            writeln!(f, "non-finite:  {} voxels", self.non_finite_voxels)?;
        }
        Ok(())
    }
}
