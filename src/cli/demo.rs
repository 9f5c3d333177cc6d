//! `posereg demo [-o DIR] [--size half] [--flexion 60]`: a phantom pair made on the spot and
//! registered (articulated initialisation, adaptive cubic-RBF, dense refinement), with its
//! figures against the known truth.

use super::settings::SettingsArgs;
use clap::Args;
use posereg::device::DeviceWanted;
use posereg::jobs::demo::{run_demo, DemoPair};
use posereg::jobs::reporter::Reporter;
use posereg::phantom::PhantomSize;
use std::path::PathBuf;

/// Arguments of `posereg demo`.
#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(short, long, default_value = "posereg-demo")]
    pub output: PathBuf,
    /// Phantom grid.
    #[arg(long, value_enum, default_value_t = PhantomSize::Half)]
    pub size: PhantomSize,
    /// Flexion of the target (degrees).
    #[arg(long, default_value_t = 30.0)]
    pub flexion: f64,
    /// Skip the articulated initialisation (the paper's first experiment, small bends).
    #[arg(long)]
    pub no_init: bool,
    /// --config, --dense, --no-dense, as for `posereg register`.
    #[command(flatten)]
    pub settings: SettingsArgs,
}

/// Makes the pair, registers it, prints the figures and where the outputs are.
pub fn run(args: &DemoArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let mut options = args.settings.options()?;
    options.initialise &= !args.no_init;
    let demo = DemoPair {
        size: args.size,
        flexion: args.flexion,
    };
    run_demo(demo, &options, &args.output, device, reporter)?;
    Ok(())
}
