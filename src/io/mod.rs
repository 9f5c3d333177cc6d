//! Files on disk: NIfTI images and labels, displacement fields (ITK convention), and the
//! atomic write every output goes through.

pub mod config;
pub mod field;
pub mod itk_transform;
pub mod kinematics;
pub mod lock;
pub mod memory;
pub mod nifti;
pub mod points;
pub mod transform;

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// The folder a file `path` is in ("." for a bare name).
fn folder_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// The whole of a text file (settings, transforms, points), refused by name when not UTF-8.
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    String::from_utf8(bytes).map_err(|_| Error::bad_file(path, "is not UTF-8 text"))
}

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
    let dir = folder_of(path);
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

/// Writes `bytes` to `path` atomically ([`write_atomically`]).
pub fn write_bytes(path: &Path, bytes: impl AsRef<[u8]>) -> Result<()> {
    write_atomically(path, |tmp| {
        std::fs::write(tmp, bytes).map_err(|e| Error::io(tmp, e))
    })
}

/// Writes `value` to `path` as pretty JSON ending in a newline, atomically.
pub fn save_json(path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(value)
        .map_err(|e| Error::bad_file(path, format!("cannot encode JSON ({e})")))?;
    write_bytes(path, text + "\n")
}

/// An output folder made ready before any computation. The folders it created are removed
/// again when it is dropped while still empty, so a run that fails leaves nothing behind.
#[must_use = "the folder is removed again when this is dropped empty"]
pub struct OutputFolder {
    /// Folders created, deepest first.
    created: Vec<PathBuf>,
    /// The folder's lock while the run writes there.
    lock: Option<lock::FolderLock>,
}

impl Drop for OutputFolder {
    fn drop(&mut self) {
        // The lock goes first: a folder holding only it is empty of outputs.
        drop(self.lock.take());
        for dir in &self.created {
            // remove_dir removes only empty folders: a run that wrote its outputs keeps them.
            if std::fs::remove_dir(dir).is_err() {
                break;
            }
        }
    }
}

/// Creates the output folder `dir` (and its parents), proves it writable by creating and
/// removing a file in it, and takes its lock (lock.rs), so an unusable folder or one another
/// run is writing into is refused before any computation.
pub fn prepare_output_folder(dir: &Path) -> Result<OutputFolder> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::bad_file(
            dir,
            "is a file, not a folder: the outputs need a folder",
        ));
    }
    let created: Vec<PathBuf> = dir
        .ancestors()
        .take_while(|d| !d.as_os_str().is_empty() && !d.exists())
        .map(Path::to_path_buf)
        .collect();
    let mut folder = OutputFolder {
        created,
        lock: None,
    };
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    probe_writable(dir, dir)?;
    folder.lock = Some(lock::lock_folder(dir)?);
    Ok(folder)
}

/// Checks before any computation that `path` can be written: not a folder, its folder exists
/// and is writable. `extensions`, when not empty, are the names it may end in.
pub fn check_output_file(path: &Path, extensions: &[&str]) -> Result<()> {
    check_output_name(path, extensions)?;
    if path.is_dir() {
        return Err(Error::bad_file(
            path,
            "is a folder; the output needs a file name",
        ));
    }
    let dir = folder_of(path);
    if !dir.is_dir() {
        return Err(Error::bad_file(path, "output folder does not exist"));
    }
    probe_writable(&dir, path)
}

/// Names a NIfTI output may end in.
pub const NIFTI_NAMES: &[&str] = &[".nii", ".nii.gz"];

/// Refuses an output name that does not end in one of `extensions` (any name when empty).
pub fn check_output_name(path: &Path, extensions: &[&str]) -> Result<()> {
    let name = path.to_string_lossy().to_ascii_lowercase();
    if !extensions.is_empty() && !extensions.iter().any(|e| name.ends_with(e)) {
        return Err(Error::bad_file(
            path,
            format!("output name must end in {}", extensions.join(" or ")),
        ));
    }
    Ok(())
}

/// Creates and removes a file in `dir`; errors name `blame`.
fn probe_writable(dir: &Path, blame: &Path) -> Result<()> {
    let probe = dir.join(format!(".posereg-probe-{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(|e| Error::bad_file(blame, format!("cannot be written ({e})")))?;
    std::fs::remove_file(&probe).map_err(|e| Error::io(&probe, e))
}
