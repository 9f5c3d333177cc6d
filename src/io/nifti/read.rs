//! Reading a NIfTI image's voxels: the header and data files found from any of their names
//! (.nii, .nii.gz, .hdr/.img pairs, gzipped or not), gzip recognised by its magic bytes, and
//! the voxel data read in chunks after checking what the header promises against the file's
//! size and the memory budget, so a lying header can neither allocate nor decompress more
//! than the promise.

use super::header::{parse, sizeof_hdr, Header};
use crate::error::{Error, Result};
use crate::io::memory;
use flate2::bufread::MultiGzDecoder;
use std::io::{BufRead, BufReader, ErrorKind, Read};
use std::path::{Path, PathBuf};

/// Deflate never expands data more than 1032-fold: a compressed file shorter than the header's
/// promise over this is truncated (or its header lies), known before decompressing anything.
const MAX_DEFLATE_RATIO: u64 = 1032;
/// Bytes decoded per chunk (a multiple of every voxel size).
const CHUNK: usize = 1 << 20;

/// An opened stream: decompressing when the file is gzip, with its size on disk.
pub struct Opened<'a> {
    reader: Box<dyn Read + 'a>,
    on_disk: u64,
    compressed: bool,
    /// Bytes (decompressed) consumed so far.
    position: u64,
}

impl<'a> Opened<'a> {
    /// Wraps `source` (`on_disk` bytes), gzipped when `gzip` says so or, when it is None,
    /// when its first two bytes are gzip's magic (a header's first bytes are sizeof_hdr, never
    /// that magic).
    pub fn new<R: BufRead + 'a>(
        mut source: R,
        on_disk: u64,
        gzip: Option<bool>,
    ) -> std::io::Result<Self> {
        let compressed = match gzip {
            Some(known) => known,
            None => source.fill_buf()?.starts_with(&[0x1f, 0x8b]),
        };
        let reader: Box<dyn Read + 'a> = if compressed {
            Box::new(MultiGzDecoder::new(source))
        } else {
            Box::new(source)
        };
        Ok(Opened {
            reader,
            on_disk,
            compressed,
            position: 0,
        })
    }

    /// Fills `buf` as far as the stream allows; returns how much was read.
    fn fill(&mut self, buf: &mut [u8], path: &Path) -> Result<usize> {
        let mut got = 0;
        while got < buf.len() {
            match self.reader.read(&mut buf[got..]) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(damaged(path, e)),
            }
        }
        self.position += got as u64;
        Ok(got)
    }

    /// Skips `n` bytes; false when the stream ended first.
    fn skip(&mut self, n: u64, path: &Path) -> Result<bool> {
        let skipped = std::io::copy(&mut (&mut self.reader).take(n), &mut std::io::sink())
            .map_err(|e| damaged(path, e))?;
        self.position += skipped;
        Ok(skipped == n)
    }
}

fn damaged(path: &Path, e: std::io::Error) -> Error {
    match e.kind() {
        ErrorKind::InvalidData | ErrorKind::InvalidInput | ErrorKind::UnexpectedEof => {
            Error::bad_file(
                path,
                format!("is damaged: its gzip stream cannot be decompressed ({e})"),
            )
        }
        _ => Error::io(path, e),
    }
}

/// Opens a file for reading (gzipped as [`Opened::new`] says), refusing folders and missing
/// files by name.
pub fn open_file(path: &Path, gzip: Option<bool>) -> Result<Opened<'static>> {
    let meta = std::fs::metadata(path).map_err(|e| match e.kind() {
        ErrorKind::NotFound => Error::bad_file(path, "no such file"),
        _ => Error::io(path, e),
    })?;
    if meta.is_dir() {
        return Err(Error::bad_file(path, "is a folder, not a NIfTI file"));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    Opened::new(BufReader::new(file), meta.len(), gzip).map_err(|e| Error::io(path, e))
}

/// The files holding an image's header and its voxels.
pub struct Files {
    /// Where the header is (.nii, .nii.gz, .hdr, .hdr.gz).
    pub header: PathBuf,
    /// Where the voxels are (the same file, or the .img beside a .hdr).
    pub data: PathBuf,
}

/// Finds the header and data files from any of their names: a .hdr or .img finds the other
/// half of its pair, gzipped or not, in the same letter case.
pub fn locate(path: &Path) -> Files {
    let same = Files {
        header: path.into(),
        data: path.into(),
    };
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else {
        return same;
    };
    let lower = name.to_ascii_lowercase();
    // (extension, the partner's extensions in the order they are looked for, is the header)
    let pairs = [
        (".hdr.gz", [".img.gz", ".img"], true),
        (".hdr", [".img", ".img.gz"], true),
        (".img.gz", [".hdr.gz", ".hdr"], false),
        (".img", [".hdr", ".hdr.gz"], false),
    ];
    for (ext, partners, is_header) in pairs {
        if !lower.ends_with(ext) {
            continue;
        }
        // to_ascii_lowercase keeps byte lengths, so the stem ends at the same byte in `name`.
        let stem = &name[..name.len() - ext.len()];
        let upper = name[stem.len()..].chars().any(|c| c.is_ascii_uppercase());
        let candidates = partners.map(|p| {
            let p = if upper {
                p.to_ascii_uppercase()
            } else {
                p.to_string()
            };
            path.with_file_name(format!("{stem}{p}"))
        });
        let partner = candidates
            .iter()
            .find(|p| p.exists())
            .unwrap_or(&candidates[0])
            .clone();
        return match is_header {
            true => Files {
                header: path.into(),
                data: partner,
            },
            false => Files {
                header: partner,
                data: path.into(),
            },
        };
    }
    same
}

/// Whether a pair's data file is gzipped, by its name: its first bytes are voxels, which may
/// be anything, gzip's magic included.
pub fn gzip_by_name(path: &Path) -> bool {
    path.to_string_lossy().to_ascii_lowercase().ends_with(".gz")
}

/// Reads and checks the header at the start of `opened`.
pub fn read_header(opened: &mut Opened, path: &Path) -> Result<Header> {
    let truncated = |got: u64| {
        Error::bad_file(
            path,
            format!("is truncated: it ends after {got} bytes, inside its header"),
        )
    };
    let mut first = [0u8; 4];
    if opened.fill(&mut first, path)? < 4 {
        return Err(truncated(opened.position));
    }
    let (version, big_endian) = sizeof_hdr(first).map_err(|p| Error::bad_file(path, p))?;
    let mut bytes = vec![0u8; version.header_size()];
    bytes[..4].copy_from_slice(&first);
    if opened.fill(&mut bytes[4..], path)? < bytes.len() - 4 {
        return Err(truncated(opened.position));
    }
    parse(&bytes, version, big_endian).map_err(|p| Error::bad_file(path, p))
}

/// Reads the voxels that `header` promises from `opened`, which is positioned
/// `skip` bytes before the first voxel, as f32 in file order with the scaling applied.
pub fn read_voxels(
    opened: &mut Opened,
    skip: u64,
    header: &Header,
    path: &Path,
) -> Result<Vec<f32>> {
    let promised = header.data_bytes();
    // Each term is below 2^60 (header.rs), so the sum cannot overflow.
    let end = opened.position + skip + promised;
    check_size(opened, end, header, path)?;
    memory::check(header.voxels() * 4 + CHUNK as u64).map_err(|p| {
        Error::bad_file(path, format!("holds {} voxels, which {p}", header.voxels()))
    })?;
    let truncated = |got: u64| {
        Error::bad_file(
            path,
            format!(
                "is truncated: its voxel data ends after {got} of the {promised} bytes its header \
                 promises (dims {:?}, {}, vox_offset {})",
                header.dims,
                header.datatype.name(),
                header.vox_offset
            ),
        )
    };
    if !opened.skip(skip, path)? {
        return Err(truncated(0));
    }
    let mut out = Vec::with_capacity(header.voxels().min(CHUNK as u64) as usize);
    let mut chunk = vec![0u8; CHUNK];
    let mut remaining = promised;
    while remaining > 0 {
        let n = remaining.min(CHUNK as u64) as usize;
        let got = opened.fill(&mut chunk[..n], path)?;
        let whole = got - got % header.datatype.size();
        header
            .datatype
            .decode(&chunk[..whole], header.big_endian, header.scaling, &mut out);
        if got < n {
            return Err(truncated(promised - remaining + got as u64));
        }
        remaining -= n as u64;
    }
    // Reading to the end of a gzip stream is what checks its CRC; more data is a wrong header.
    if opened.compressed && opened.fill(&mut [0u8; 1], path)? > 0 {
        return Err(more_than_promised(header, path));
    }
    Ok(out)
}

fn more_than_promised(header: &Header, path: &Path) -> Error {
    Error::bad_file(
        path,
        format!(
            "holds more voxel data than its header promises (dims {:?}, {}, vox_offset {}): the \
             header is wrong",
            header.dims,
            header.datatype.name(),
            header.vox_offset
        ),
    )
}

/// Refuses a file whose size cannot match the header before anything is allocated: exactly
/// `end` bytes for an uncompressed file, at least `end / 1032` for a gzipped one.
fn check_size(opened: &Opened, end: u64, header: &Header, path: &Path) -> Result<()> {
    if opened.compressed {
        if opened.on_disk.saturating_mul(MAX_DEFLATE_RATIO) < end {
            return Err(Error::bad_file(
                path,
                format!(
                    "is truncated: {} compressed bytes cannot hold the {end} bytes its header \
                     promises (dims {:?}, {})",
                    opened.on_disk,
                    header.dims,
                    header.datatype.name()
                ),
            ));
        }
        return Ok(());
    }
    if opened.on_disk > end {
        return Err(more_than_promised(header, path));
    }
    if opened.on_disk < end {
        return Err(Error::bad_file(
            path,
            format!(
                "is truncated: it has {} bytes, its header promises {end} (vox_offset {} + dims \
                 {:?} of {})",
                opened.on_disk,
                header.vox_offset,
                header.dims,
                header.datatype.name()
            ),
        ));
    }
    Ok(())
}
