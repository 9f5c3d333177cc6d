//! `posereg bench [--size half] [--flexion 30] [--runs 3] [--backends cpu|gpu|both]`: the whole
//! registration of a phantom pair on each backend, the median per stage over several runs, the
//! GPU/CPU ratio, and peak memory. `--device cpu|gpu` times that backend alone, `--gpu` picks
//! the adapter.

use anyhow::bail;
use clap::{Args, ValueEnum};
use posereg::device::{DeviceChoice, DeviceWanted};
use posereg::jobs::bench::run_bench;
use posereg::jobs::demo::DemoPair;
use posereg::jobs::reporter::Reporter;
use posereg::phantom::PhantomSize;

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

/// Runs and prints the table.
pub fn run(args: &BenchArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let kinds: &[DeviceChoice] = match backends(args, device)? {
        Which::Cpu => &[DeviceChoice::Cpu],
        Which::Gpu => &[DeviceChoice::Gpu],
        Which::Both => &[DeviceChoice::Cpu, DeviceChoice::Gpu],
    };
    let demo = DemoPair {
        size: args.size,
        flexion: args.flexion,
    };
    let adapter = device.adapter.clone();
    run_bench(demo, args.runs, (kinds, adapter), reporter)?;
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
