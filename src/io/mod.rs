//! Files on disk: NIfTI images and labels, displacement fields (ITK convention), and the
//! atomic write every output goes through.

pub mod config;
pub mod field;
pub mod nifti;
pub mod memory;
pub mod transform;

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// Writes `path` through a temporary file in the same folder that `write` fills, renamed into
/// place only when `write` succeeded, so a failure or interruption never leaves a half-written
/// output under the real name. The temporary name keeps the real name's extension because
/// writers (nifti) choose compression from it.
pub fn write_atomically<F>(path: &Path, write: F) -> Result<()>
where
    F: FnOnce(&Path) -> Result<()>,
{
    let name = path
        .file_name()
        .ok_or_else(|| Error::bad_file(path, "output path has no file name"))?
        .to_string_lossy()
        .into_owned();
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(Error::bad_file(path, "output folder does not exist"));
    }
    let tmp = dir.join(format!(".posereg-tmp-{}-{name}", std::process::id()));
    let result =
        write(&tmp).and_then(|()| std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e)));
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}
