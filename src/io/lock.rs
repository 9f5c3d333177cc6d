//! The lock an output folder holds while a run writes into it: `DIR/.posereg.lock`, holding the
//! run's process id and host. A second run into the folder is refused while the first is
//! alive; a lock left by a run that was killed (its process gone, same host) is taken over, so
//! an interrupted run never leaves its folder stuck.

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// The lock file's name inside the folder.
pub const LOCK_NAME: &str = ".posereg.lock";

/// A folder's lock, removed when dropped.
#[derive(Debug)]
pub struct FolderLock {
    path: PathBuf,
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Takes `dir`'s lock, or refuses naming the run that holds it.
pub fn lock_folder(dir: &Path) -> Result<FolderLock> {
    let path = dir.join(LOCK_NAME);
    let ours = format!("{} {}\n", std::process::id(), host());
    // Written whole under a private name, then linked into place: the link fails when a lock
    // exists, so two runs never both take it and a lock is never seen half-written.
    let staged = dir.join(format!(".posereg-lock-{}", std::process::id()));
    std::fs::write(&staged, &ours).map_err(|e| Error::io(&staged, e))?;
    let taken = take(&path, &staged);
    let _ = std::fs::remove_file(&staged);
    taken?;
    Ok(FolderLock { path })
}

/// Links `staged` to `path`; once over a stale lock.
fn take(path: &Path, staged: &Path) -> Result<()> {
    for _ in 0..2 {
        match std::fs::hard_link(staged, path) {
            Ok(()) => return Ok(()),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                let holder = std::fs::read_to_string(path).unwrap_or_default();
                if !is_stale(&holder) {
                    return Err(in_use(path, &holder));
                }
                std::fs::remove_file(path).map_err(|e| Error::io(path, e))?;
            }
            Err(e) => return Err(Error::io(path, e)),
        }
    }
    Err(Error::bad_file(
        path,
        "another run took the folder's lock meanwhile",
    ))
}

/// A lock whose process is gone, on this host.
fn is_stale(holder: &str) -> bool {
    let mut words = holder.split_whitespace();
    let pid = words.next().and_then(|p| p.parse::<u32>().ok());
    match (pid, words.next()) {
        (Some(pid), Some(h)) if h == host() => !alive(pid),
        _ => false,
    }
}

fn in_use(path: &Path, holder: &str) -> Error {
    let folder = path.parent().unwrap_or(path);
    let mut words = holder.split_whitespace();
    let (pid, on) = (words.next().unwrap_or("?"), words.next().unwrap_or("?"));
    Error::bad_file(
        folder,
        format!(
            "is in use by another posereg run (process {pid} on {on}, {}); wait for it, choose \
             another folder, or remove the lock if no run is writing there",
            path.display()
        ),
    )
}

/// This machine's name as a lock records it (a lock from another host on a shared disk cannot
/// be checked).
pub fn host() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .ok()
        .filter(|h| !h.is_empty() && !h.contains(char::is_whitespace))
        .unwrap_or_else(|| "this-host".to_string())
}

/// Whether process `pid` exists.
#[cfg(unix)]
fn alive(pid: u32) -> bool {
    let Ok(pid) = i32::try_from(pid) else {
        return false;
    };
    // SAFETY: signal 0 sends nothing; it only asks whether the process exists.
    let found = unsafe { libc::kill(pid, 0) } == 0;
    found || std::io::Error::last_os_error().raw_os_error() == Some(libc::EPERM)
}

/// Without a way to ask, a lock is taken to be held.
#[cfg(not(unix))]
fn alive(_pid: u32) -> bool {
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_live_lock_refuses_and_a_dead_one_is_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let first = lock_folder(dir.path()).unwrap();
        let err = lock_folder(dir.path()).unwrap_err().to_string();
        assert!(err.contains("in use by another posereg run"), "{err}");
        assert!(err.contains(&std::process::id().to_string()), "{err}");
        drop(first);
        assert!(!dir.path().join(LOCK_NAME).exists());
        let mut gone = std::process::Command::new("true").spawn().unwrap();
        let pid = gone.id();
        gone.wait().unwrap();
        std::fs::write(dir.path().join(LOCK_NAME), format!("{pid} {}\n", host())).unwrap();
        let again = lock_folder(dir.path()).unwrap();
        let held = std::fs::read_to_string(dir.path().join(LOCK_NAME)).unwrap();
        assert!(
            held.starts_with(&format!("{} ", std::process::id())),
            "{held}"
        );
        drop(again);
        std::fs::write(dir.path().join(LOCK_NAME), "1 another-host\n").unwrap();
        assert!(
            lock_folder(dir.path()).is_err(),
            "a lock from another host is kept"
        );
        let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(leftovers.len(), 1, "only the other host's lock remains");
    }
}
