//! The `posereg` command: parse, call the library, exit non-zero with one line on failure.

mod cli;

use clap::Parser;

fn main() {
    die_quietly_on_a_closed_pipe();
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
