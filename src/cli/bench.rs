//! `posereg bench [--size half] [--flexion 30] [--runs 3] [--device cpu|gpu|both]`: the whole
//! registration of a phantom pair on each backend, the median per stage over several runs, the
//! GPU/CPU ratio, and peak memory.

use clap::{Args, ValueEnum};
use posereg::backend::Backend;
use posereg::cpu::CpuBackend;
use posereg::gpu::GpuBackend;
use posereg::phantom::{generate, PhantomSize, PhantomSpec};
use posereg::progress::Silent;
use posereg::register::{register, RegisterOptions, StageTimes};

/// Which backends to time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Which {
    /// The CPU backend only.
    Cpu,
    /// The GPU path only.
    Gpu,
    /// Both, and their ratio.
    Both,
}

/// Arguments of `posereg bench`.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Phantom grid.
    #[arg(long, value_enum, default_value_t = PhantomSize::Half)]
    pub size: PhantomSize,
    /// Flexion of the target (degrees).
    #[arg(long, default_value_t = 30.0)]
    pub flexion: f64,
    /// Runs per backend (the median is reported).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u64).range(1..=100))]
    pub runs: u64,
    /// Backends to time.
    #[arg(long = "backends", value_enum, default_value_t = Which::Both)]
    pub which: Which,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Peak resident memory of this process so far (Linux), in MiB.
fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

fn time(
    backend: &dyn Backend,
    runs: u64,
    pair: &(posereg::phantom::Phantom, posereg::phantom::Phantom),
) -> anyhow::Result<[f64; 4]> {
    let mut all: Vec<StageTimes> = Vec::new();
    for _ in 0..runs {
        let r = register(
            backend,
            &pair.0.image,
            &pair.0.labels,
            &pair.1.image,
            &RegisterOptions::default(),
            &Silent,
        )?;
        all.push(r.timings);
    }
    let m = |f: fn(&StageTimes) -> f64| median(all.iter().map(f).collect());
    Ok([
        m(|t| t.initialisation),
        m(|t| t.adaptive),
        m(|t| t.finish),
        m(|t| t.initialisation + t.adaptive + t.finish),
    ])
}

/// Runs and prints the table.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let spec = |flexion_degrees, seed| PhantomSpec {
        size: args.size,
        flexion_degrees,
        seed,
        ..Default::default()
    };
    let pair = (generate(&spec(0.0, 1))?, generate(&spec(args.flexion, 2))?);
    println!(
        "{:?} phantom {:?}, {}° flexion, median of {} runs",
        args.size,
        args.size.dims(),
        args.flexion,
        args.runs
    );
    println!(
        "{:<52} {:>10} {:>10} {:>10} {:>10}",
        "backend", "init s", "adaptive s", "finish s", "total s"
    );
    let mut totals = Vec::new();
    if args.which != Which::Gpu {
        let t = time(&CpuBackend, args.runs, &pair)?;
        println!(
            "{:<52} {:>10.2} {:>10.2} {:>10.2} {:>10.2}",
            CpuBackend.describe(),
            t[0],
            t[1],
            t[2],
            t[3]
        );
        println!(
            "  peak host memory (process so far): {:.0} MiB",
            peak_rss_mib().unwrap_or(f64::NAN)
        );
        totals.push(t);
    }
    if args.which != Which::Cpu {
        let gpu = GpuBackend::new()?;
        let t = time(&gpu, args.runs, &pair)?;
        println!(
            "{:<52} {:>10.2} {:>10.2} {:>10.2} {:>10.2}",
            gpu.describe(),
            t[0],
            t[1],
            t[2],
            t[3]
        );
        println!(
            "  peak host memory (process so far): {:.0} MiB; largest set of device buffers bound at once: {:.1} MiB",
            peak_rss_mib().unwrap_or(f64::NAN),
            gpu.peak_dispatch_bytes() as f64 / (1024.0 * 1024.0)
        );
        totals.push(t);
    }
    if let [cpu, gpu] = totals.as_slice() {
        println!(
            "GPU/CPU time: init {:.2}×, adaptive {:.2}×, total {:.2}×",
            gpu[0] / cpu[0],
            gpu[1] / cpu[1],
            gpu[3] / cpu[3]
        );
    }
    Ok(())
}
