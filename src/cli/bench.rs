//! `posereg bench [--size half] [--flexion 30] [--runs 3] [--backends cpu|gpu|both]`: the whole
//! registration of a phantom pair on each backend, the median per stage over several runs, the
//! GPU/CPU ratio, and peak memory. `--device cpu|gpu` times that backend alone, `--gpu` picks
//! the adapter.

use anyhow::bail;
use clap::{Args, ValueEnum};
use posereg::backend::Core;
use posereg::device::{open_backend, DeviceChoice, DeviceWanted, Opened};
use posereg::on_backend;
use posereg::phantom::{generate, PhantomSize, PhantomSpec};
use posereg::pipeline::bench::{peak_rss_mib, time_registrations, Sizes, Timed};

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

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

/// One backend's row of the table and its traffic lines.
fn print_row(describe: &str, timed: &Timed, sizes: &Sizes) {
    let t = &timed.stages;
    println!(
        "{describe:<52} {:>10.2} {:>10.2} {:>10.2} {:>10.2} {:>10.2}",
        t.initialisation, t.adaptive, t.dense, t.finish, timed.total
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
    let pair = (generate(&spec(0.0, 1))?, generate(&spec(args.flexion, 2))?);
    println!(
        "{:?} phantom {:?}, {}° flexion, median of {} runs",
        args.size,
        args.size.dims(),
        args.flexion,
        args.runs
    );
    let pair = (&pair.0, &pair.1);
    let sizes = Sizes::of(pair);
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
    let kinds = [
        (Which::Cpu, DeviceChoice::Cpu),
        (Which::Gpu, DeviceChoice::Gpu),
    ];
    for (_, kind) in kinds
        .into_iter()
        .filter(|(w, _)| which == *w || which == Which::Both)
    {
        let wanted = DeviceWanted {
            kind,
            adapter: device.adapter.clone(),
        };
        let (opened, _) = open_backend(&wanted)?;
        let t = on_backend!(opened, backend => time_registrations(backend, args.runs, pair))?;
        print_row(
            &on_backend!(opened, backend => backend.describe()),
            &t,
            &sizes,
        );
        let peak = peak_rss_mib().unwrap_or(f64::NAN);
        match &opened {
            Opened::Cpu(_) => println!("  peak host memory (process so far): {peak:.0} MiB"),
            Opened::Gpu(gpu) => println!(
                "  peak host memory (process so far): {peak:.0} MiB; largest set of device buffers bound at once: {:.1} MiB",
                mib(gpu.peak_dispatch_bytes())
            ),
        }
        totals.push(t);
    }
    if let [cpu, gpu] = totals.as_slice() {
        let (c, g) = (&cpu.stages, &gpu.stages);
        let ratio = |g: f64, c: f64| match c > 0.0 {
            true => format!("{:.2}×", g / c),
            false => "–".into(),
        };
        println!(
            "GPU/CPU time: init {}, adaptive {}, dense {}, total {}",
            ratio(g.initialisation, c.initialisation),
            ratio(g.adaptive, c.adaptive),
            ratio(g.dense, c.dense),
            ratio(gpu.total, cpu.total)
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
