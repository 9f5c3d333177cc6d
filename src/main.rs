//! The `posereg` command: parse, call the library, exit non-zero with one line on failure.

mod cli;

use clap::Parser;

fn main() {
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
