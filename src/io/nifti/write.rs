//! Writing NIfTI-1 images and label maps (.nii, .nii.gz): the affine stored exactly in the
//! sform and its nearest rotation+zooms in the qform (what nibabel does), both with code 1
//! (scanner), so every reader lands on the same world frame.

use crate::error::{Error, Result};
use crate::io::{check_output_name, NIFTI_NAMES};
use crate::volume::{Affine, Labels, Volume};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use ndarray::{ArrayD, IxDyn, ShapeBuilder};
use nifti::{NiftiHeader, NiftiType};
use std::path::Path;

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

impl DataType {
    /// The values an integer type holds (writing saturates beyond them); None for floats.
    pub fn integer_range(self) -> Option<(f32, f32)> {
        match self {
            DataType::U8 => Some((0.0, u8::MAX as f32)),
            DataType::I16 => Some((i16::MIN as f32, i16::MAX as f32)),
            DataType::U16 => Some((0.0, u16::MAX as f32)),
            DataType::I32 => Some((i32::MIN as f32, i32::MAX as f32)),
            DataType::F32 | DataType::F64 => None,
        }
    }
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
    check_output_name(path, NIFTI_NAMES)?;
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
    crate::io::write_atomically(path, |tmp| {
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
