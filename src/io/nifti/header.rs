//! NIfTI-1 and NIfTI-2 headers in either byte order, decoded and checked against the
//! specification before a single voxel is read: magic, dims, datatype against bitpix,
//! vox_offset, intensity scaling, spatial units and the fields that place the grid.

use super::datatype::Datatype;
use crate::volume::Affine;
use nalgebra::Matrix3;

/// Bytes in a NIfTI-1 header (sizeof_hdr).
pub const NIFTI1_SIZE: usize = 348;
/// Bytes in a NIfTI-2 header (sizeof_hdr).
pub const NIFTI2_SIZE: usize = 540;
/// Offsets and sizes beyond this (1 EiB) are no file's: refusing them keeps every sum of an
/// offset and a size far from overflowing.
const MAX_BYTES: u64 = 1 << 60;
/// A single-file image's header is followed by 4 bytes of extension flags.
const EXTENSION_FLAGS: u64 = 4;

/// Which NIfTI.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Version {
    /// 348-byte header, 16-bit dims.
    #[serde(rename = "NIfTI-1")]
    Nifti1,
    /// 540-byte header, 64-bit dims (nibabel's Nifti2Image).
    #[serde(rename = "NIfTI-2")]
    Nifti2,
}

impl Version {
    /// "NIfTI-1" or "NIfTI-2".
    pub fn name(self) -> &'static str {
        match self {
            Version::Nifti1 => "NIfTI-1",
            Version::Nifti2 => "NIfTI-2",
        }
    }

    /// Header size in bytes.
    pub fn header_size(self) -> usize {
        match self {
            Version::Nifti1 => NIFTI1_SIZE,
            Version::Nifti2 => NIFTI2_SIZE,
        }
    }
}

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

/// A decoded header: every field posereg uses, in f64 and usize whatever the version.
#[derive(Clone, Debug)]
pub struct Header {
    /// NIfTI-1 or NIfTI-2.
    pub version: Version,
    /// Byte order of the header and the voxels.
    pub big_endian: bool,
    /// The voxels are in a separate .img file (magic "ni1"/"ni2"), not after the header.
    pub paired: bool,
    /// dim[1..=dim[0]].
    pub dims: Vec<usize>,
    /// The voxel type.
    pub datatype: Datatype,
    /// pixdim[0..8] as stored (pixdim[0] is qfac).
    pub pixdim: [f64; 8],
    /// Byte offset of the first voxel in the file that holds the voxels.
    pub vox_offset: u64,
    /// (scl_slope, scl_inter) when the voxels are scaled (slope ≠ 0), else None.
    pub scaling: Option<(f64, f64)>,
    /// intent_code.
    pub intent_code: i32,
    /// Millimetres per spatial unit of the header (xyzt_units: metres 1000, microns 0.001).
    pub mm_per_unit: f64,
    qform_code: i32,
    sform_code: i32,
    quatern: [f64; 3],
    qoffset: [f64; 3],
    srow: [[f64; 4]; 3],
}

/// Reads fixed-width fields at byte offsets in one byte order.
struct Fields<'a> {
    bytes: &'a [u8],
    big_endian: bool,
}

macro_rules! field_reader {
    ($($name:ident: $t:ty),*) => {$(
        fn $name(&self, at: usize) -> $t {
            const N: usize = std::mem::size_of::<$t>();
            let raw: [u8; N] = self.bytes[at..at + N].try_into().expect("N bytes");
            if self.big_endian { <$t>::from_be_bytes(raw) } else { <$t>::from_le_bytes(raw) }
        }
    )*};
}

impl Fields<'_> {
    field_reader!(i16: i16, i32: i32, i64: i64, f32: f32, f64: f64);
}

/// The version and byte order that the first four bytes (sizeof_hdr) announce.
pub fn sizeof_hdr(first: [u8; 4]) -> Result<(Version, bool), String> {
    for (version, size) in [
        (Version::Nifti1, NIFTI1_SIZE),
        (Version::Nifti2, NIFTI2_SIZE),
    ] {
        if i32::from_le_bytes(first) == size as i32 {
            return Ok((version, false));
        }
        if i32::from_be_bytes(first) == size as i32 {
            return Ok((version, true));
        }
    }
    Err(format!(
        "is not a NIfTI file: sizeof_hdr is {} (NIfTI-1 has 348, NIfTI-2 540)",
        i32::from_le_bytes(first)
    ))
}

/// Decodes and checks a whole header (`bytes` holds exactly `version.header_size()` bytes).
pub fn parse(bytes: &[u8], version: Version, big_endian: bool) -> Result<Header, String> {
    let f = Fields { bytes, big_endian };
    let layout = Layout::of(version);
    let magic_len = match version {
        Version::Nifti1 => 4,
        Version::Nifti2 => 8,
    };
    let paired = check_magic(&bytes[layout.magic..layout.magic + magic_len], version)?;
    let dims = dims(&f, version)?;
    let datatype = Datatype::from_code(f.i16(layout.datatype))?;
    let bitpix = f.i16(layout.bitpix);
    if bitpix as usize != 8 * datatype.size() {
        return Err(format!(
            "bitpix is {bitpix} but datatype {} has {} bits per voxel",
            datatype.name(),
            8 * datatype.size()
        ));
    }
    voxel_bytes(&dims, datatype)?;
    let float = |at: usize| match version {
        Version::Nifti1 => f.f32(at) as f64,
        Version::Nifti2 => f.f64(at),
    };
    let int = |at: usize| match version {
        Version::Nifti1 => f.i16(at) as i32,
        Version::Nifti2 => f.i32(at),
    };
    let vox_offset = vox_offset(&f, version, paired)?;
    let scaling = scaling(float(layout.scl_slope), float(layout.scl_inter))?;
    let units = match version {
        Version::Nifti1 => bytes[layout.xyzt_units] as i32,
        Version::Nifti2 => f.i32(layout.xyzt_units),
    };
    let step = match version {
        Version::Nifti1 => 4,
        Version::Nifti2 => 8,
    };
    Ok(Header {
        version,
        big_endian,
        paired,
        dims,
        datatype,
        pixdim: std::array::from_fn(|i| float(layout.pixdim + i * step)),
        vox_offset,
        scaling,
        intent_code: int(layout.intent_code),
        mm_per_unit: mm_per_unit(units)?,
        qform_code: int(layout.qform_code),
        sform_code: int(layout.sform_code),
        quatern: std::array::from_fn(|i| float(layout.quatern + i * step)),
        qoffset: std::array::from_fn(|i| float(layout.quatern + (3 + i) * step)),
        srow: std::array::from_fn(|r| {
            std::array::from_fn(|c| float(layout.srow + (4 * r + c) * step))
        }),
    })
}

/// Byte offsets of the fields posereg reads, per version.
struct Layout {
    magic: usize,
    dim: usize,
    intent_code: usize,
    datatype: usize,
    bitpix: usize,
    pixdim: usize,
    vox_offset: usize,
    scl_slope: usize,
    scl_inter: usize,
    xyzt_units: usize,
    qform_code: usize,
    sform_code: usize,
    quatern: usize,
    srow: usize,
}

impl Layout {
    fn of(version: Version) -> Layout {
        match version {
            Version::Nifti1 => Layout {
                magic: 344,
                dim: 40,
                intent_code: 68,
                datatype: 70,
                bitpix: 72,
                pixdim: 76,
                vox_offset: 108,
                scl_slope: 112,
                scl_inter: 116,
                xyzt_units: 123,
                qform_code: 252,
                sform_code: 254,
                quatern: 256,
                srow: 280,
            },
            Version::Nifti2 => Layout {
                magic: 4,
                dim: 16,
                intent_code: 504,
                datatype: 12,
                bitpix: 14,
                pixdim: 104,
                vox_offset: 168,
                scl_slope: 176,
                scl_inter: 184,
                xyzt_units: 500,
                qform_code: 344,
                sform_code: 348,
                quatern: 352,
                srow: 400,
            },
        }
    }
}

/// True for a header whose voxels are in a separate .img file.
fn check_magic(magic: &[u8], version: Version) -> Result<bool, String> {
    // NIfTI-2's magic goes on with \r\n\x1a\n, which a text-mode transfer damages.
    let (single, paired): (&[u8], &[u8]) = match version {
        Version::Nifti1 => (b"n+1\0", b"ni1\0"),
        Version::Nifti2 => (b"n+2\0\r\n\x1a\n", b"ni2\0\r\n\x1a\n"),
    };
    if magic == single {
        Ok(false)
    } else if magic == paired {
        Ok(true)
    } else {
        Err(format!(
            "has no NIfTI magic (found {:?}): an Analyze 7.5 header or a damaged file; posereg \
             reads NIfTI-1 and NIfTI-2",
            String::from_utf8_lossy(magic)
        ))
    }
}

fn dims(f: &Fields, version: Version) -> Result<Vec<usize>, String> {
    let at = Layout::of(version).dim;
    let dim = |i: usize| match version {
        Version::Nifti1 => f.i16(at + 2 * i) as i64,
        Version::Nifti2 => f.i64(at + 8 * i),
    };
    let ndim = dim(0);
    if !(1..=7).contains(&ndim) {
        return Err(format!(
            "dim[0] is {ndim}: the number of dimensions must be 1 to 7"
        ));
    }
    (1..=ndim as usize)
        .map(|i| match dim(i) {
            d if d >= 1 => Ok(d as usize),
            d => Err(format!(
                "dim[{i}] is {d}: every dimension must be at least 1"
            )),
        })
        .collect()
}

/// Bytes of voxel data the dims promise, or why that cannot be.
pub fn voxel_bytes(dims: &[usize], datatype: Datatype) -> Result<u64, String> {
    dims.iter()
        .try_fold(datatype.size() as u64, |n, &d| n.checked_mul(d as u64))
        .filter(|&n| n < MAX_BYTES)
        .ok_or_else(|| format!("dims {dims:?} promise more voxel data than any file can hold"))
}

fn vox_offset(f: &Fields, version: Version, paired: bool) -> Result<u64, String> {
    let at = Layout::of(version).vox_offset;
    let value = match version {
        Version::Nifti1 => f.f32(at) as f64,
        Version::Nifti2 => f.i64(at) as f64,
    };
    if !(value.is_finite() && value >= 0.0 && value.fract() == 0.0 && value < MAX_BYTES as f64) {
        return Err(format!(
            "vox_offset is {value}: it must be a whole number of bytes within a file"
        ));
    }
    let least = if paired {
        0
    } else {
        version.header_size() as u64 + EXTENSION_FLAGS
    };
    if (value as u64) < least {
        return Err(format!(
            "vox_offset is {value}, inside the header: the voxels of a single-file {} \
             start at byte {least} or later",
            version.name()
        ));
    }
    Ok(value as u64)
}

/// The specification: scl_slope 0 means the voxels are not scaled; nifti1_io and nibabel read
/// a slope that is not finite the same way. A used slope with a non-finite intercept would
/// make every voxel NaN.
fn scaling(slope: f64, inter: f64) -> Result<Option<(f64, f64)>, String> {
    if slope == 0.0 || !slope.is_finite() {
        return Ok(None);
    }
    if !inter.is_finite() {
        return Err(format!(
            "scl_inter is {inter} with scl_slope {slope}: every voxel would be {inter}"
        ));
    }
    Ok(Some((slope, inter)))
}

fn mm_per_unit(xyzt_units: i32) -> Result<f64, String> {
    match xyzt_units & 0x07 {
        0 | 2 => Ok(1.0), // unknown (read as mm, as nibabel and ITK do) or mm
        1 => Ok(1000.0),  // metres
        3 => Ok(0.001),   // microns
        code => Err(format!(
            "xyzt_units gives spatial unit code {code}, which NIfTI does not define"
        )),
    }
}

impl Header {
    /// Voxel count over all dims.
    pub fn voxels(&self) -> u64 {
        self.dims.iter().map(|&d| d as u64).product()
    }

    /// Bytes between a single file's header and its first voxel (vox_offset is checked to
    /// lie past the header).
    pub fn gap(&self) -> u64 {
        self.vox_offset - self.version.header_size() as u64
    }

    /// Bytes of voxel data.
    pub fn data_bytes(&self) -> u64 {
        self.voxels() * self.datatype.size() as u64
    }

    /// The voxel→world affine (RAS mm) by the rule nibabel and ITK share: the sform when
    /// sform_code > 0, else the qform when qform_code > 0, else diag(pixdim). Fields that
    /// define the grid must be finite; pixdim, where it scales the grid, must be positive.
    pub fn affine(&self) -> Result<(Affine, AffineSource), String> {
        let (mut m, source) = if self.sform_code > 0 {
            (self.sform()?, AffineSource::Sform)
        } else if self.qform_code > 0 {
            (self.qform()?, AffineSource::Qform)
        } else {
            let zooms = self.zooms("there is neither an sform nor a qform, so pixdim")?;
            (
                Affine::from_diagonal(&nalgebra::Vector4::new(zooms[0], zooms[1], zooms[2], 1.0)),
                AffineSource::Pixdim,
            )
        };
        for r in 0..3 {
            for c in 0..4 {
                m[(r, c)] *= self.mm_per_unit;
            }
        }
        Ok((m, source))
    }

    fn sform(&self) -> Result<Affine, String> {
        if self.srow.iter().flatten().any(|v| !v.is_finite()) {
            return Err("the sform (srow_x, srow_y, srow_z) holds NaN or Inf".into());
        }
        let mut m = Affine::identity();
        for (r, row) in self.srow.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                m[(r, c)] = *v;
            }
        }
        Ok(m)
    }

    fn zooms(&self, what: &str) -> Result<[f64; 3], String> {
        let zooms = [self.pixdim[1], self.pixdim[2], self.pixdim[3]];
        if zooms.iter().all(|z| z.is_finite() && *z > 0.0) {
            Ok(zooms)
        } else {
            Err(format!("{what} defines the voxel size, but pixdim[1..3] is {zooms:?}: each must be a positive number"))
        }
    }

    fn qform(&self) -> Result<Affine, String> {
        let zooms = self.zooms("the qform is used, and pixdim")?;
        let [b, c, d] = self.quatern;
        let norm2 = b * b + c * c + d * d;
        if self
            .quatern
            .iter()
            .chain(&self.qoffset)
            .any(|v| !v.is_finite())
            || norm2 > 1.0 + 1e-5
        {
            return Err(format!(
                "the qform's quaternion ({b}, {c}, {d}) or offset {:?} is not a rotation",
                self.qoffset
            ));
        }
        // The header stores only b, c, d of a unit quaternion with a >= 0.
        let a = (1.0 - norm2).max(0.0).sqrt();
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
        // qfac = pixdim[0]: −1 flips the third axis; the specification reads 0 as 1.
        let qfac = if self.pixdim[0] < 0.0 { -1.0 } else { 1.0 };
        let mut m = Affine::identity();
        for row in 0..3 {
            m[(row, 0)] = r[(row, 0)] * zooms[0];
            m[(row, 1)] = r[(row, 1)] * zooms[1];
            m[(row, 2)] = r[(row, 2)] * zooms[2] * qfac;
            m[(row, 3)] = self.qoffset[row];
        }
        Ok(m)
    }
}
