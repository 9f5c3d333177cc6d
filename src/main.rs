//! The `posereg` command: parse, call the library, exit non-zero with one line on failure.

mod cli;

use clap::Parser;

fn main() {
    die_quietly_on_a_closed_pipe();
    reuse_freed_volumes();
    let parsed = cli::Cli::parse();
    quiet_mesa();
    if let Err(e) = cli::run(parsed) {
        eprintln!("posereg: error: {e:#}");
        std::process::exit(1);
    }
}

/// Mesa's Vulkan drivers print "XDG_RUNTIME_DIR is invalid" on every start when the variable is
/// unset (as in containers and CI); point it at a private folder so probing stays silent.
fn quiet_mesa() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return;
    }
    let dir = std::env::temp_dir().join("posereg-xdg");
    if std::fs::create_dir_all(&dir).is_ok() {
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700));
        }
        std::env::set_var("XDG_RUNTIME_DIR", &dir);
    }
}

/// `posereg info --json x.nii.gz | head -3`: Rust ignores SIGPIPE, so a write to a pipe whose
/// reader has gone fails and `println!` panics. Restore the default every Unix tool has: the
/// process ends quietly when nobody reads its output any more.
fn die_quietly_on_a_closed_pipe() {
    #[cfg(unix)]
    // SAFETY: called first thing in main, before any thread starts; it only resets one
    // signal's disposition to the system default.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// The CPU backend allocates each kernel's output afresh (volumes of 8–40 MiB at 1 mm) and
/// frees it soon after. With glibc's defaults such blocks are mapped and unmapped each time
/// (above its dynamic mmap threshold) or handed back by heap trimming, and every reuse faults
/// its pages in again, zeroed by the kernel: 1.5–1.9 million page faults and 2.4–2.9 s of
/// system time in a 19 s registration (1 mm 90° knee). Keeping freed memory in the process
/// lets the next volume reuse it (BENCHMARKS.md, thirty-ninth session). The mmap threshold is
/// fixed at glibc's largest (32 MiB, larger blocks are still mapped so that the heap does not
/// fragment around them), the heap is never trimmed, and it grows 256 MiB of address space at
/// a time (pages are only backed once written).
fn reuse_freed_volumes() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: called first thing in main, before any thread starts or any large allocation;
    // mallopt only changes the allocator's tuning parameters.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
        libc::mallopt(libc::M_TOP_PAD, 256 << 20);
    }
}
