//! `posereg bench [--size half] [--flexion 30] [--runs 3] [--backends cpu|gpu|both]`: the whole
//! registration of a phantom pair on each backend, the median per stage over several runs, the
//! GPU/CPU ratio, and peak memory. `--device cpu|gpu` times that backend alone, `--gpu` picks
//! the adapter.

use anyhow::bail;
use clap::{Args, ValueEnum};
use posereg::backend::{Backend, Core};
use posereg::cpu::CpuBackend;
use posereg::device::{DeviceChoice, DeviceWanted};
use posereg::gpu::context::GpuContext;
use posereg::gpu::GpuBackend;
use posereg::nonrigid::adaptive::Evaluations;
use posereg::phantom::{generate, PhantomSize, PhantomSpec};
use posereg::pipeline::register::{register, Inputs, RegisterOptions, StageTimes, StageTraffic};
use posereg::progress::Silent;

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
    /// Backends to time (`--device cpu` or `gpu` alone narrows it to that one).
    #[arg(long = "backends", value_enum, default_value_t = Which::Both)]
    pub which: Which,
}

/// The backends to time: `--backends`, narrowed by `--device cpu|gpu`; an error where the two
/// ask for different ones.
fn backends(args: &BenchArgs, device: &DeviceWanted) -> anyhow::Result<Which> {
    Ok(match (device.kind, args.which) {
        (DeviceChoice::Auto, which) => which,
        (DeviceChoice::Cpu, Which::Gpu) | (DeviceChoice::Gpu, Which::Cpu) => bail!(
            "--device {} and --backends {} ask for different backends",
            flag_value(device.kind),
            flag_value(args.which)
        ),
        (DeviceChoice::Cpu, _) => Which::Cpu,
        (DeviceChoice::Gpu, _) => Which::Gpu,
    })
}

/// A flag's value as it is written on the command line.
fn flag_value(value: impl ValueEnum) -> String {
    value
        .to_possible_value()
        .map_or_else(|| "?".into(), |v| v.get_name().to_string())
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

/// Median seconds per stage (initialisation, adaptive, dense, finish, total) and the traffic of the
/// last run (the same every run: the work is deterministic).
struct Timed {
    seconds: [f64; 5],
    traffic: StageTraffic,
    evaluations: Evaluations,
}

fn time<B: Backend>(
    backend: &B,
    runs: u64,
    pair: &(posereg::phantom::Phantom, posereg::phantom::Phantom),
) -> anyhow::Result<Timed> {
    let mut all: Vec<StageTimes> = Vec::new();
    let mut traffic = StageTraffic::default();
    let mut evaluations = Evaluations::default();
    for _ in 0..runs {
        let r = register(
            backend,
            Inputs::new(&pair.0.image, &pair.0.labels, &pair.1.image),
            &RegisterOptions::default(),
            &Silent,
        )?;
        all.push(r.timings);
        (traffic, evaluations) = (r.traffic, r.adaptive.evaluations);
    }
    let m = |f: fn(&StageTimes) -> f64| median(all.iter().map(f).collect());
    Ok(Timed {
        seconds: [
            m(|t| t.initialisation),
            m(|t| t.adaptive),
            m(|t| t.dense),
            m(|t| t.finish),
            m(|t| t.total()),
        ],
        traffic,
        evaluations,
    })
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

/// Bytes of a registration's input volumes (source, labels, target as f32) and of the volumes it
/// writes (field, warped source and Jacobian on the target's grid; the inverse field on the
/// source's).
struct Sizes {
    inputs: u64,
    outputs: u64,
}

/// One backend's row of the table and its traffic lines.
fn print_row(describe: &str, timed: &Timed, sizes: &Sizes) {
    let t = timed.seconds;
    println!(
        "{describe:<52} {:>10.2} {:>10.2} {:>10.2} {:>10.2} {:>10.2}",
        t[0], t[1], t[2], t[3], t[4]
    );
    let stages = &timed.traffic;
    for (stage, traffic) in [
        ("initialisation", stages.initialisation),
        ("adaptive", stages.adaptive),
        ("dense", stages.dense),
        ("finish", stages.finish),
        ("registration", stages.total),
    ] {
        println!(
            "  {stage:<15} up {:>9.2} MiB, down {:>9.2} MiB, {:>7} dispatches, {:>7} submits",
            mib(traffic.bytes_up),
            mib(traffic.bytes_down),
            traffic.dispatches,
            traffic.submits
        );
    }
    println!(
        "  registration    up {:.2}× its inputs, down {:.2}× its outputs",
        stages.total.bytes_up as f64 / sizes.inputs as f64,
        stages.total.bytes_down as f64 / sizes.outputs as f64
    );
    let e = &timed.evaluations;
    let per = |v: u64| v as f64 / e.count.max(1) as f64;
    println!(
        "  per evaluation ({} evaluations): up {:.1} KiB, down {:.1} KiB (most {:.1} KiB), {:.1} dispatches, {:.1} submits",
        e.count,
        per(e.traffic.bytes_up) / 1024.0,
        per(e.traffic.bytes_down) / 1024.0,
        e.most_bytes_down as f64 / 1024.0,
        per(e.traffic.dispatches),
        per(e.traffic.submits)
    );
}

/// Runs and prints the table.
pub fn run(args: &BenchArgs, device: &DeviceWanted) -> anyhow::Result<()> {
    let which = backends(args, device)?;
    let spec = |flexion_degrees, seed| PhantomSpec {
        size: args.size,
        flexion_degrees,
        seed,
        ..Default::default()
    };
    let pair = (
        generate(&posereg::cpu::CpuBackend, &spec(0.0, 1))?,
        generate(&posereg::cpu::CpuBackend, &spec(args.flexion, 2))?,
    );
    println!(
        "{:?} phantom {:?}, {}° flexion, median of {} runs",
        args.size,
        args.size.dims(),
        args.flexion,
        args.runs
    );
    let voxels = |p: &posereg::phantom::Phantom| p.image.grid.len() as u64;
    let sizes = Sizes {
        inputs: 4 * (2 * voxels(&pair.0) + voxels(&pair.1)),
        outputs: 20 * voxels(&pair.1) + 12 * voxels(&pair.0),
    };
    println!(
        "inputs (source, labels, target as f32): {:.2} MiB; outputs (field, warped, Jacobian, inverse field): {:.2} MiB",
        mib(sizes.inputs),
        mib(sizes.outputs)
    );
    println!(
        "{:<52} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "backend", "init s", "adaptive s", "dense s", "finish s", "total s"
    );
    let mut totals = Vec::new();
    if which != Which::Gpu {
        let t = time(&CpuBackend, args.runs, &pair)?;
        print_row(&CpuBackend.describe(), &t, &sizes);
        println!(
            "  peak host memory (process so far): {:.0} MiB",
            peak_rss_mib().unwrap_or(f64::NAN)
        );
        totals.push(t.seconds);
    }
    if which != Which::Cpu {
        let gpu = GpuBackend::with_context(GpuContext::open(device.adapter.as_ref())?)?;
        let t = time(&gpu, args.runs, &pair)?;
        print_row(&gpu.describe(), &t, &sizes);
        println!(
            "  peak host memory (process so far): {:.0} MiB; largest set of device buffers bound at once: {:.1} MiB",
            peak_rss_mib().unwrap_or(f64::NAN),
            gpu.peak_dispatch_bytes() as f64 / (1024.0 * 1024.0)
        );
        totals.push(t.seconds);
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

#[cfg(test)]
mod tests {
    use super::*;

    fn args(which: Which) -> BenchArgs {
        BenchArgs {
            size: PhantomSize::Quarter,
            flexion: 10.0,
            runs: 1,
            which,
        }
    }

    fn device(kind: DeviceChoice) -> DeviceWanted {
        DeviceWanted {
            kind,
            adapter: None,
        }
    }

    #[test]
    fn device_narrows_the_backends_and_a_contradiction_is_refused() {
        use DeviceChoice::{Auto, Cpu, Gpu};
        for which in [Which::Cpu, Which::Gpu, Which::Both] {
            assert_eq!(backends(&args(which), &device(Auto)).unwrap(), which);
        }
        assert_eq!(
            backends(&args(Which::Both), &device(Cpu)).unwrap(),
            Which::Cpu
        );
        assert_eq!(
            backends(&args(Which::Both), &device(Gpu)).unwrap(),
            Which::Gpu
        );
        assert_eq!(
            backends(&args(Which::Cpu), &device(Cpu)).unwrap(),
            Which::Cpu
        );
        let refused = backends(&args(Which::Gpu), &device(Cpu)).unwrap_err();
        assert_eq!(
            refused.to_string(),
            "--device cpu and --backends gpu ask for different backends"
        );
        assert!(backends(&args(Which::Cpu), &device(Gpu)).is_err());
    }
}
