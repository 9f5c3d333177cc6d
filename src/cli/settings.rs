//! The settings file and the dense refinement's flags, shared by `register`, `demo` and
//! `series`: the defaults, overridden by the file, overridden by the flags.

use clap::Args;
use posereg::io::config::load_options;
use posereg::pipeline::register::RegisterOptions;
use std::path::{Path, PathBuf};

/// `--config`, `--dense` and `--no-dense`.
#[derive(Args, Debug)]
pub struct SettingsArgs {
    /// Settings file (.toml or .json) holding any of the settings `posereg register --help`
    /// lists; flags given here override it.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Run the dense refinement (dense.enabled = true), whatever the settings file says; on
    /// by default.
    #[arg(long, conflicts_with = "no_dense")]
    pub dense: bool,
    /// Skip the dense refinement (dense.enabled = false), whatever the settings file says.
    #[arg(long)]
    pub no_dense: bool,
}

impl SettingsArgs {
    /// The settings file's options (the defaults without one), the dense flags applied.
    pub fn options(&self) -> anyhow::Result<RegisterOptions> {
        let mut options = settings_file(self.config.as_deref())?;
        if self.dense {
            options.dense.enabled = true;
        }
        if self.no_dense {
            options.dense.enabled = false;
        }
        Ok(options)
    }
}

/// The settings `config` holds, or the defaults without one.
fn settings_file(config: Option<&Path>) -> anyhow::Result<RegisterOptions> {
    Ok(match config {
        Some(path) => load_options(path)?,
        None => RegisterOptions::default(),
    })
}
