//! NIfTI voxel types: which codes posereg reads, their sizes, and the decoding of raw bytes
//! (either byte order) to f32 with the header's intensity scaling.

/// A voxel type posereg reads. Complex, RGB, 1-bit and 128-bit types are refused by name in
/// [`Datatype::from_code`]: none of them is an intensity or a label.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Datatype {
    /// DT_UINT8 (2)
    U8,
    /// DT_INT8 (256)
    I8,
    /// DT_INT16 (4)
    I16,
    /// DT_UINT16 (512)
    U16,
    /// DT_INT32 (8)
    I32,
    /// DT_UINT32 (768)
    U32,
    /// DT_INT64 (1024)
    I64,
    /// DT_UINT64 (1280)
    U64,
    /// DT_FLOAT32 (16)
    F32,
    /// DT_FLOAT64 (64)
    F64,
}

impl Datatype {
    /// The type of a header's datatype code, or why posereg cannot read it.
    pub fn from_code(code: i16) -> Result<Self, String> {
        let refused = |name: &str| {
            Err(format!(
                "datatype {code} ({name}) is not supported: posereg reads integer and real \
                 scalar images"
            ))
        };
        Ok(match code {
            2 => Datatype::U8,
            256 => Datatype::I8,
            4 => Datatype::I16,
            512 => Datatype::U16,
            8 => Datatype::I32,
            768 => Datatype::U32,
            1024 => Datatype::I64,
            1280 => Datatype::U64,
            16 => Datatype::F32,
            64 => Datatype::F64,
            0 => return Err("datatype is 0 (DT_UNKNOWN): the voxel type is not given".into()),
            1 => return refused("binary, 1 bit per voxel"),
            32 => return refused("complex64"),
            128 => return refused("RGB24"),
            1536 => return refused("float128"),
            1792 => return refused("complex128"),
            2048 => return refused("complex256"),
            2304 => return refused("RGBA32"),
            _ => return Err(format!("datatype code {code} is not a NIfTI datatype")),
        })
    }

    /// Bytes per voxel.
    pub fn size(self) -> usize {
        match self {
            Datatype::U8 | Datatype::I8 => 1,
            Datatype::I16 | Datatype::U16 => 2,
            Datatype::I32 | Datatype::U32 | Datatype::F32 => 4,
            Datatype::I64 | Datatype::U64 | Datatype::F64 => 8,
        }
    }

    /// The name nibabel and numpy give it.
    pub fn name(self) -> &'static str {
        match self {
            Datatype::U8 => "uint8",
            Datatype::I8 => "int8",
            Datatype::I16 => "int16",
            Datatype::U16 => "uint16",
            Datatype::I32 => "int32",
            Datatype::U32 => "uint32",
            Datatype::I64 => "int64",
            Datatype::U64 => "uint64",
            Datatype::F32 => "float32",
            Datatype::F64 => "float64",
        }
    }

    /// Appends the voxels of `bytes` (whole voxels, in file order) to `out` as f32, each
    /// scaled by `slope · v + inter` in f64 when `scaling` is given.
    pub fn decode(
        self,
        bytes: &[u8],
        big_endian: bool,
        scaling: Option<(f64, f64)>,
        out: &mut Vec<f32>,
    ) {
        macro_rules! each {
            ($t:ty) => {{
                const N: usize = std::mem::size_of::<$t>();
                let value = |c: &[u8]| {
                    let raw: [u8; N] = c.try_into().expect("chunks_exact gives N bytes");
                    if big_endian {
                        <$t>::from_be_bytes(raw)
                    } else {
                        <$t>::from_le_bytes(raw)
                    }
                };
                match scaling {
                    Some((slope, inter)) => out.extend(
                        bytes
                            .chunks_exact(N)
                            .map(|c| (slope * value(c) as f64 + inter) as f32),
                    ),
                    None => out.extend(bytes.chunks_exact(N).map(|c| value(c) as f32)),
                }
            }};
        }
        match self {
            Datatype::U8 => each!(u8),
            Datatype::I8 => each!(i8),
            Datatype::I16 => each!(i16),
            Datatype::U16 => each!(u16),
            Datatype::I32 => each!(i32),
            Datatype::U32 => each!(u32),
            Datatype::I64 => each!(i64),
            Datatype::U64 => each!(u64),
            Datatype::F32 => each!(f32),
            Datatype::F64 => each!(f64),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_byte_orders_and_scaling_decode_alike() {
        let mut out = Vec::new();
        Datatype::I16.decode(&[0x01, 0x02, 0xff, 0xff], false, None, &mut out);
        Datatype::I16.decode(&[0x02, 0x01, 0xff, 0xff], true, Some((0.5, 10.0)), &mut out);
        assert_eq!(out, vec![513.0, -1.0, 266.5, 9.5]);
    }

    #[test]
    fn unsupported_types_are_named() {
        for (code, name) in [
            (32, "complex64"),
            (128, "RGB24"),
            (2304, "RGBA32"),
            (0, "DT_UNKNOWN"),
        ] {
            let err = Datatype::from_code(code).unwrap_err();
            assert!(err.contains(name), "{err}");
        }
        assert!(Datatype::from_code(7)
            .unwrap_err()
            .contains("not a NIfTI datatype"));
    }
}
