//! NIfTI images and label maps in world space.
//!
//! Reading follows the specification and refuses what it cannot read faithfully: NIfTI-1 and
//! NIfTI-2 in either byte order, single files (.nii, .nii.gz) and .hdr/.img pairs found from
//! either name; vox_offset honoured and checked against the file's size; bitpix checked against
//! the datatype; complex, RGB and other non-scalar types refused by name; the decompressed size
//! capped by what the header promises and checked against the memory budget before allocating.
//! The voxel→world affine follows the rule nibabel and ITK share: the sform when
//! sform_code > 0, else the qform when qform_code > 0, else a plain pixdim scaling, converted
//! to millimetres by xyzt_units.

mod datatype;
mod describe;
mod header;
mod read;
mod write;

pub use datatype::Datatype;
pub use describe::{describe, Description};
pub use header::{AffineSource, Header, Version};
pub use write::{header_for, save_labels, save_volume, write_image, DataType};

use crate::error::{Error, Result};
use crate::volume::{Affine, Grid, Image, Labels, Volume};
use read::{gzip_by_name, locate, open_file, read_header as read_header_from, read_voxels, Opened};
use std::path::Path;

/// What a NIfTI header says, decoded.
#[derive(Clone, Debug)]
pub struct HeaderInfo {
    /// The header as read (its `dims` are dim[1..=dim[0]]).
    pub header: Header,
    /// Voxel→world RAS mm.
    pub affine: Affine,
    /// Where the affine came from.
    pub affine_source: AffineSource,
}

impl HeaderInfo {
    fn new(header: Header, path: &Path) -> Result<Self> {
        let (affine, affine_source) = header.affine().map_err(|p| Error::bad_file(path, p))?;
        Ok(HeaderInfo {
            header,
            affine,
            affine_source,
        })
    }
}

/// Header + voxel values (scaled by scl_slope/scl_inter) in file order, as f32.
pub struct RawImage {
    /// The decoded header.
    pub info: HeaderInfo,
    /// Values, x fastest, all dims flattened.
    pub data: Vec<f32>,
}

/// Reads and checks the header of an image (no voxels are read).
pub fn read_header(path: &Path) -> Result<HeaderInfo> {
    let files = locate(path);
    let header = read_header_from(&mut open_file(&files.header, None)?, &files.header)?;
    HeaderInfo::new(header, &files.header)
}

/// Reads any NIfTI-1 or NIfTI-2 image with integer or real voxels, applying the scaling.
pub fn read_raw(path: &Path) -> Result<RawImage> {
    let files = locate(path);
    let mut opened = open_file(&files.header, None)?;
    let header = read_header_from(&mut opened, &files.header)?;
    let info = HeaderInfo::new(header, &files.header)?;
    let data = if info.header.paired {
        let mut data_file = open_file(&files.data, Some(gzip_by_name(&files.data)))?;
        read_voxels(
            &mut data_file,
            info.header.vox_offset,
            &info.header,
            &files.data,
        )?
    } else if files.data != files.header {
        return Err(Error::bad_file(
            &files.data,
            format!(
                "its header {} is a single-file NIfTI (magic n+1), not the header of a pair",
                files.header.display()
            ),
        ));
    } else {
        read_voxels(&mut opened, info.header.gap(), &info.header, path)?
    };
    Ok(RawImage { info, data })
}

/// Reads a single-file image (.nii or .nii.gz) held in memory; `name` names it in errors.
pub fn read_raw_bytes(name: &Path, bytes: &[u8]) -> Result<RawImage> {
    let mut opened =
        Opened::new(bytes, bytes.len() as u64, None).map_err(|e| Error::io(name, e))?;
    let header = read_header_from(&mut opened, name)?;
    let info = HeaderInfo::new(header, name)?;
    if info.header.paired {
        return Err(Error::bad_file(
            name,
            "its voxels are in a separate .img file",
        ));
    }
    let data = read_voxels(&mut opened, info.header.gap(), &info.header, name)?;
    Ok(RawImage { info, data })
}

/// The 3-D grid of an image whose dims beyond the third are all 1.
pub fn spatial_grid(path: &Path, info: &HeaderInfo, what: &str) -> Result<Grid> {
    let dims = &info.header.dims;
    let extra: usize = dims.iter().skip(3).product();
    if extra != 1 {
        return Err(Error::bad_file(
            path,
            format!("{what} must be a 3-D image, but its dims are {dims:?}"),
        ));
    }
    let d3 = [
        dims[0],
        *dims.get(1).unwrap_or(&1),
        *dims.get(2).unwrap_or(&1),
    ];
    Grid::new(d3, info.affine).map_err(|e| Error::bad_file(path, e.to_string()))
}

/// Non-finite voxels of an intensity image (read from `path`, or handed over under that name)
/// are an error: they would poison every sum.
pub fn check_finite(path: &Path, data: &[f32]) -> Result<()> {
    match data.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => {
            let bad = data.iter().filter(|v| !v.is_finite()).count();
            Err(Error::bad_file(
                path,
                format!(
                    "has {bad} non-finite voxels (NaN, Inf, or beyond float32's range), the first \
                     at index {i}"
                ),
            ))
        }
    }
}

/// An intensity image from its raw read. Non-finite voxels are an error: they would poison
/// every sum.
pub fn volume_from_raw(path: &Path, raw: RawImage) -> Result<Volume> {
    let grid = spatial_grid(path, &raw.info, "an intensity image")?;
    check_finite(path, &raw.data)?;
    Ok(Image {
        grid,
        data: raw.data,
    })
}

/// A label map from its raw read; values must be whole numbers in 0..=65535.
pub fn labels_from_raw(path: &Path, raw: RawImage) -> Result<Labels> {
    let grid = spatial_grid(path, &raw.info, "a label map")?;
    let mut data = Vec::with_capacity(raw.data.len());
    for v in &raw.data {
        if !(v.is_finite() && *v >= 0.0 && *v <= 65535.0 && v.fract() == 0.0) {
            return Err(Error::bad_file(
                path,
                format!("label value {v} is not a whole number in 0..=65535"),
            ));
        }
        data.push(*v as u16);
    }
    Ok(Image { grid, data })
}

/// Loads a 3-D intensity image.
pub fn load_volume(path: &Path) -> Result<Volume> {
    volume_from_raw(path, read_raw(path)?)
}

/// Loads a 3-D label map.
pub fn load_labels(path: &Path) -> Result<Labels> {
    labels_from_raw(path, read_raw(path)?)
}
