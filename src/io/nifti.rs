//! NIfTI-1 images and label maps (.nii, .nii.gz) in world space.
//!
//! Reading follows the rule nibabel and ITK share for the voxel→world affine: the sform when
//! sform_code > 0, else the qform when qform_code > 0, else a plain pixdim scaling. Writing
//! stores the affine exactly in the sform and its nearest rotation+zooms in the qform (what
//! nibabel does), both with code 1 (scanner), so every reader lands on the same world frame.

use crate::error::{Error, Result};
use crate::volume::{Affine, Grid, Image, Labels, Volume};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use ndarray::{ArrayD, IxDyn, ShapeBuilder};
use nifti::{IntoNdArray, NiftiHeader, NiftiObject, NiftiType, ReaderOptions};
use std::path::Path;

/// Which header field the affine came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum AffineSource {
    /// sform_code > 0.
    Sform,
    /// qform_code > 0 and no sform.
    Qform,
    /// Neither code set: diag(pixdim), origin at voxel 0 (ITK's reading).
    Pixdim,
}

/// On-disk voxel types posereg writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DataType {
    /// unsigned 8-bit
    U8,
    /// signed 16-bit
    I16,
    /// unsigned 16-bit
    U16,
    /// signed 32-bit
    I32,
    /// 32-bit float
    F32,
    /// 64-bit float
    F64,
}

/// What a NIfTI header says, decoded.
#[derive(Clone, Debug)]
pub struct HeaderInfo {
    /// All dims from dim[1..=dim[0]].
    pub dims: Vec<usize>,
    /// Datatype name as the nifti crate reports it.
    pub datatype: String,
    /// Voxel sizes from pixdim[1..=3] (mm).
    pub pixdim: [f64; 3],
    /// Voxel→world RAS mm.
    pub affine: Affine,
    /// Where the affine came from.
    pub affine_source: AffineSource,
    /// scl_slope, scl_inter as stored.
    pub scaling: (f32, f32),
    /// intent_code as stored.
    pub intent_code: i16,
}

/// The raw header, decoded into what posereg needs.
pub fn header_info(path: &Path, h: &NiftiHeader) -> Result<HeaderInfo> {
    let ndim = h.dim[0] as usize;
    if !(1..=7).contains(&ndim) {
        return Err(Error::bad_file(
            path,
            format!("dim[0] = {} is not 1..7", h.dim[0]),
        ));
    }
    let dims: Vec<usize> = h.dim[1..=ndim].iter().map(|&d| d as usize).collect();
    if dims.contains(&0) {
        return Err(Error::bad_file(
            path,
            format!("has an empty dimension: {dims:?}"),
        ));
    }
    let datatype = h
        .data_type()
        .map(|t| format!("{t:?}"))
        .map_err(|_| Error::bad_file(path, format!("unknown datatype code {}", h.datatype)))?;
    let pixdim = [h.pixdim[1] as f64, h.pixdim[2] as f64, h.pixdim[3] as f64];
    let (affine, affine_source) = header_affine(h);
    Ok(HeaderInfo {
        dims,
        datatype,
        pixdim,
        affine,
        affine_source,
        scaling: (h.scl_slope, h.scl_inter),
        intent_code: h.intent_code,
    })
}

/// The voxel→world affine by the sform > qform > pixdim rule.
pub fn header_affine(h: &NiftiHeader) -> (Affine, AffineSource) {
    if h.sform_code > 0 {
        let mut m = Affine::identity();
        for (r, row) in [h.srow_x, h.srow_y, h.srow_z].iter().enumerate() {
            for c in 0..4 {
                m[(r, c)] = row[c] as f64;
            }
        }
        return (m, AffineSource::Sform);
    }
    let zooms = [h.pixdim[1] as f64, h.pixdim[2] as f64, h.pixdim[3] as f64];
    if h.qform_code > 0 {
        let (b, c, d) = (h.quatern_b as f64, h.quatern_c as f64, h.quatern_d as f64);
        // The header stores only b, c, d of a unit quaternion with a >= 0.
        let a = (1.0 - (b * b + c * c + d * d)).max(0.0).sqrt();
        let r = Matrix3::new(
            a * a + b * b - c * c - d * d,
            2.0 * (b * c - a * d),
            2.0 * (b * d + a * c),
            2.0 * (b * c + a * d),
            a * a + c * c - b * b - d * d,
            2.0 * (c * d - a * b),
            2.0 * (b * d - a * c),
            2.0 * (c * d + a * b),
            a * a + d * d - c * c - b * b,
        );
        let qfac = if h.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
        let mut m = Affine::identity();
        for row in 0..3 {
            m[(row, 0)] = r[(row, 0)] * zooms[0];
            m[(row, 1)] = r[(row, 1)] * zooms[1];
            m[(row, 2)] = r[(row, 2)] * zooms[2] * qfac;
        }
        m[(0, 3)] = h.quatern_x as f64;
        m[(1, 3)] = h.quatern_y as f64;
        m[(2, 3)] = h.quatern_z as f64;
        return (m, AffineSource::Qform);
    }
    let mut m = Affine::identity();
    for (i, z) in zooms.iter().enumerate() {
        m[(i, i)] = if *z > 0.0 { *z } else { 1.0 };
    }
    (m, AffineSource::Pixdim)
}

/// Header + voxel values (scaled by scl_slope/scl_inter) in file order, as f32.
pub struct RawImage {
    /// The decoded header.
    pub info: HeaderInfo,
    /// The header itself, for writers that want to copy fields.
    pub header: NiftiHeader,
    /// Values, x fastest, all dims flattened.
    pub data: Vec<f32>,
}

/// Reads any NIfTI-1 file the nifti crate understands, applying the intensity scaling.
pub fn read_raw(path: &Path) -> Result<RawImage> {
    if !path.exists() {
        return Err(Error::bad_file(path, "no such file"));
    }
    let obj = ReaderOptions::new()
        .read_file(path)
        .map_err(|e| Error::bad_file(path, format!("not a readable NIfTI-1 file ({e})")))?;
    let header = obj.header().clone();
    let info = header_info(path, &header)?;
    let expected: usize = info.dims.iter().product();
    let volume = obj.into_volume();
    let array: ArrayD<f32> = volume
        .into_ndarray::<f32>()
        .map_err(|e| Error::bad_file(path, format!("cannot decode voxel data ({e})")))?;
    if array.len() != expected {
        return Err(Error::bad_file(
            path,
            format!("holds {} voxels, header says {expected}", array.len()),
        ));
    }
    // Iterating the transposed view visits axis 0 fastest: the file's order, whatever the
    // array's memory layout.
    let data = array.t().iter().copied().collect();
    Ok(RawImage { info, header, data })
}

fn spatial_grid(path: &Path, info: &HeaderInfo, what: &str) -> Result<Grid> {
    let dims = &info.dims;
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

/// Loads a 3-D intensity image. Non-finite voxels are an error: they would poison every sum.
pub fn load_volume(path: &Path) -> Result<Volume> {
    let raw = read_raw(path)?;
    let grid = spatial_grid(path, &raw.info, "an intensity image")?;
    if let Some(i) = raw.data.iter().position(|v| !v.is_finite()) {
        let bad = raw.data.iter().filter(|v| !v.is_finite()).count();
        return Err(Error::bad_file(
            path,
            format!("has {bad} non-finite voxels (NaN or Inf), the first at index {i}"),
        ));
    }
    Ok(Image {
        grid,
        data: raw.data,
    })
}

/// Loads a 3-D label map; values must be whole numbers in 0..=65535.
pub fn load_labels(path: &Path) -> Result<Labels> {
    let raw = read_raw(path)?;
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

/// A header for `dims` placed by `affine`: sform exact, qform the nearest rotation + zooms.
pub fn header_for(dims: &[usize], affine: &Affine, datatype: NiftiType) -> Result<NiftiHeader> {
    let mut dim = [1u16; 8];
    dim[0] = dims.len() as u16;
    for (i, d) in dims.iter().enumerate() {
        dim[i + 1] = u16::try_from(*d)
            .ok()
            .filter(|&v| v <= i16::MAX as u16)
            .ok_or_else(|| Error::InvalidInput(format!("dimension {d} exceeds NIfTI-1's 32767")))?;
    }
    let mut h = NiftiHeader {
        dim,
        datatype: datatype as i16,
        bitpix: (datatype.size_of() * 8) as i16,
        xyzt_units: 2, // NIFTI_UNITS_MM
        sform_code: 1,
        qform_code: 1,
        srow_x: std::array::from_fn(|c| affine[(0, c)] as f32),
        srow_y: std::array::from_fn(|c| affine[(1, c)] as f32),
        srow_z: std::array::from_fn(|c| affine[(2, c)] as f32),
        ..NiftiHeader::default()
    };
    set_qform(&mut h, affine);
    Ok(h)
}

/// nibabel's `set_qform`: split the linear part into zooms and a rotation (flipping the third
/// axis when the determinant is negative, recorded in qfac = pixdim[0]), replace the rotation by
/// its nearest orthonormal matrix (polar decomposition by SVD), store as a quaternion.
fn set_qform(h: &mut NiftiHeader, affine: &Affine) {
    let m: Matrix3<f64> = affine.fixed_view::<3, 3>(0, 0).into_owned();
    let mut zooms: [f64; 3] = std::array::from_fn(|c| m.column(c).norm());
    let mut r = m;
    for (c, zoom) in zooms.iter().enumerate() {
        r.column_mut(c).unscale_mut(*zoom);
    }
    let mut qfac = 1.0;
    if r.determinant() < 0.0 {
        qfac = -1.0;
        zooms[2] = -zooms[2];
        r.column_mut(2).neg_mut();
    }
    let svd = r.svd(true, true);
    let (u, vt) = (svd.u.expect("requested"), svd.v_t.expect("requested"));
    let rot = Rotation3::from_matrix_unchecked(u * vt);
    let mut q = UnitQuaternion::from_rotation_matrix(&rot).into_inner();
    if q.w < 0.0 {
        q = -q;
    }
    h.quatern_b = q.i as f32;
    h.quatern_c = q.j as f32;
    h.quatern_d = q.k as f32;
    h.quatern_x = affine[(0, 3)] as f32;
    h.quatern_y = affine[(1, 3)] as f32;
    h.quatern_z = affine[(2, 3)] as f32;
    h.pixdim[0] = qfac as f32;
    for (i, zoom) in zooms.iter().enumerate() {
        h.pixdim[i + 1] = zoom.abs() as f32;
    }
}

/// Writes `data` (x fastest, `dims` as given) through the atomic writer, converting to `dtype`
/// (integers rounded to nearest and clamped to the type's range).
pub fn write_image(
    path: &Path,
    dims: &[usize],
    affine: &Affine,
    data: &[f32],
    dtype: DataType,
    customise: impl FnOnce(&mut NiftiHeader),
) -> Result<()> {
    let name = path.to_string_lossy();
    if !(name.ends_with(".nii") || name.ends_with(".nii.gz")) {
        return Err(Error::bad_file(
            path,
            "output name must end in .nii or .nii.gz",
        ));
    }
    let shape = IxDyn(dims).f();
    let nifti_type = match dtype {
        DataType::U8 => NiftiType::Uint8,
        DataType::I16 => NiftiType::Int16,
        DataType::U16 => NiftiType::Uint16,
        DataType::I32 => NiftiType::Int32,
        DataType::F32 => NiftiType::Float32,
        DataType::F64 => NiftiType::Float64,
    };
    let mut header = header_for(dims, affine, nifti_type)?;
    customise(&mut header);
    super::write_atomically(path, |tmp| {
        let opts = nifti::writer::WriterOptions::new(tmp).reference_header(&header);
        let written = match dtype {
            DataType::U8 => opts.write_nifti(&convert::<u8>(shape, data)?),
            DataType::I16 => opts.write_nifti(&convert::<i16>(shape, data)?),
            DataType::U16 => opts.write_nifti(&convert::<u16>(shape, data)?),
            DataType::I32 => opts.write_nifti(&convert::<i32>(shape, data)?),
            DataType::F32 => opts.write_nifti(&convert::<f32>(shape, data)?),
            DataType::F64 => opts.write_nifti(&convert::<f64>(shape, data)?),
        };
        written.map_err(|e| Error::bad_file(path, format!("cannot write ({e})")))
    })
}

fn convert<T: FromF32>(shape: ndarray::Shape<IxDyn>, data: &[f32]) -> Result<ArrayD<T>> {
    let values: Vec<T> = data.iter().map(|&v| T::from_f32(v)).collect();
    ArrayD::from_shape_vec(shape, values)
        .map_err(|e| Error::InvalidInput(format!("data does not fit its dims ({e})")))
}

/// Saturating conversion from f32 to an on-disk voxel type.
trait FromF32 {
    fn from_f32(v: f32) -> Self;
}
macro_rules! int_from_f32 {
    ($($t:ty),*) => {$(
        impl FromF32 for $t {
            fn from_f32(v: f32) -> Self {
                // `as` saturates at the type's bounds and maps NaN to 0.
                v.round() as $t
            }
        }
    )*};
}
int_from_f32!(u8, i16, u16, i32);
impl FromF32 for f32 {
    fn from_f32(v: f32) -> Self {
        v
    }
}
impl FromF32 for f64 {
    fn from_f32(v: f32) -> Self {
        v as f64
    }
}

/// Saves a scalar volume in the chosen voxel type.
pub fn save_volume(path: &Path, volume: &Volume, dtype: DataType) -> Result<()> {
    let g = &volume.grid;
    write_image(path, &g.dims, &g.affine, &volume.data, dtype, |_| {})
}

/// Saves a label map (uint8 when every label fits, else uint16).
pub fn save_labels(path: &Path, labels: &Labels) -> Result<()> {
    let dtype = if labels.data.iter().all(|&l| l <= 255) {
        DataType::U8
    } else {
        DataType::U16
    };
    let values: Vec<f32> = labels.data.iter().map(|&l| l as f32).collect();
    let g = &labels.grid;
    write_image(path, &g.dims, &g.affine, &values, dtype, |_| {})
}
