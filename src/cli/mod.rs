//! The command-line verbs: each parses its arguments, calls the library, and prints.

pub mod apply;
pub mod bench;
pub mod bend;
pub mod demo;
pub mod devices;
pub mod eval;
pub mod info;
pub mod init;
pub mod phantom;
pub mod points;
pub mod pose;
pub mod register;
pub mod resample;
pub mod series;
pub mod settings;

use clap::{Parser, Subcommand, ValueEnum};
use posereg::abi::Blending;
use posereg::device::{DeviceChoice, DeviceWanted};
use posereg::gpu::context::AdapterChoice;
use posereg::jobs::reporter::Reporter;

/// Register 3-D MRI of an articulated body across poses (GPU, with a CPU twin).
#[derive(Parser, Debug)]
#[command(name = "posereg", version, about)]
pub struct Cli {
    /// Where kernels run: auto picks a hardware GPU when present, else the CPU backend.
    #[arg(long, value_enum, global = true, default_value_t = DeviceChoice::Auto)]
    pub device: DeviceChoice,
    /// Which GPU: its index in `posereg devices`' list, or part of its name (implies the GPU
    /// path unless --device cpu).
    #[arg(long, global = true)]
    pub gpu: Option<AdapterChoice>,
    /// No progress bars or log lines on stderr (errors and the result line still print).
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// CPU threads for the CPU backend and the host's work (default: every core, or
    /// RAYON_NUM_THREADS), so that jobs can share a machine.
    #[arg(long, global = true, value_parser = clap::value_parser!(u16).range(1..=4096))]
    pub threads: Option<u16>,
    /// The verb.
    #[command(subcommand)]
    pub command: Command,
}

/// The verbs.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Apply a registration to another image (a label map with --nearest).
    Apply(apply::ApplyArgs),
    /// Carry points (CSV, world mm) through a registration.
    ApplyPoints(points::PointsArgs),
    /// Time the whole registration of a phantom pair on each backend.
    Bench(bench::BenchArgs),
    /// Bend a labelled straight volume by volume skeletal deformation, with the truth.
    Bend(bend::BendArgs),
    /// Make a phantom pair, register it, and print the figures against the truth.
    Demo(demo::DemoArgs),
    /// List the GPUs (Vulkan adapters) with the index --gpu takes.
    Devices,
    /// The paper's figures for an estimated field against a true one.
    Eval(eval::EvalArgs),
    /// Print a NIfTI file's grid, world affine, orientation and intensity range.
    Info(info::InfoArgs),
    /// Articulated initialisation alone: per-bone rigid, skinning, volume skeletal deformation.
    Init(init::InitArgs),
    /// Make a knee phantom in any flexion, with exact ground truth.
    Phantom(phantom::PhantomArgs),
    /// Re-pose a labelled scan at given knee angles and translations, with the truth.
    Pose(pose::PoseArgs),
    /// Register a straight scan with bone labels to a bent scan: the whole pipeline.
    Register(register::RegisterArgs),
    /// Resample an image through a displacement field (ITK convention) onto a target grid.
    Resample(resample::ResampleArgs),
    /// Register one labelled scan to several poses in order, each seeded by the one before.
    Series(series::SeriesArgs),
}

/// Runs the parsed command line on a pool of `--threads` workers (default: every core).
///
/// The command runs on one of the pool's workers rather than beside them: the host's serial
/// steps between kernels otherwise compete for the cores with the idle workers spinning for
/// work (half phantom 60°, 2 cores: 5.99 → 5.86 s, BENCHMARKS.md, twenty-third session). The
/// Python module runs its registrations the same way.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = cli.threads {
        pool = pool.num_threads(threads as usize);
    }
    let reporter = Reporter::new(cli.quiet);
    let device = DeviceWanted {
        kind: cli.device,
        adapter: cli.gpu,
    };
    pool.build()?
        .install(|| run_command(cli.command, &device, &reporter))
}

/// Runs one verb.
fn run_command(command: Command, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    match command {
        Command::Apply(args) => apply::run(&args, device, reporter),
        Command::ApplyPoints(args) => points::run(&args, reporter),
        Command::Bench(args) => bench::run(&args, device, reporter),
        Command::Bend(args) => bend::run(&args, device, reporter),
        Command::Demo(args) => demo::run(&args, device, reporter),
        Command::Devices => devices::run(),
        Command::Eval(args) => eval::run(&args),
        Command::Info(args) => info::run(&args),
        Command::Init(args) => init::run(&args, device, reporter),
        Command::Phantom(args) => phantom::run(&args),
        Command::Pose(args) => pose::run(&args, device, reporter),
        Command::Register(args) => register::run(&args, device, reporter),
        Command::Resample(args) => resample::run(&args, device, reporter),
        Command::Series(args) => series::run(&args, device, reporter),
    }
}

/// --blending's values, named as the settings file names them: the library's `Blending` is
/// ABI vocabulary and knows nothing of the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BlendingFlag {
    /// Σ_j w_j M_j (the paper's linear blend skinning).
    Linear,
    /// The normalised blend of the motions' unit dual quaternions.
    DualQuaternion,
}

impl From<BlendingFlag> for Blending {
    fn from(flag: BlendingFlag) -> Self {
        match flag {
            BlendingFlag::Linear => Blending::Linear,
            BlendingFlag::DualQuaternion => Blending::DualQuaternion,
        }
    }
}
