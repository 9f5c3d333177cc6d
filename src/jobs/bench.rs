//! The whole registration of a phantom pair timed on each backend (`posereg bench`): the median
//! per stage over several runs, the bytes each stage moves between host and device, the
//! GPU/CPU ratio and peak memory, told as a table.

use super::demo::DemoPair;
use crate::backend::Core;
use crate::device::{open_backend, DeviceChoice, DeviceWanted, Opened};
use crate::error::Result;
use crate::gpu::context::AdapterChoice;
use crate::pipeline::bench::{peak_rss_mib, time_registrations, Sizes, Timed};
use crate::progress::Progress;

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

/// Times `runs` registrations of the phantom pair `demo` on each backend of `kinds` (the GPU
/// `adapter` picks, when given) and tells the table.
pub fn run_bench(
    demo: DemoPair,
    runs: u64,
    (kinds, adapter): (&[DeviceChoice], Option<AdapterChoice>),
    progress: &dyn Progress,
) -> Result<()> {
    let pair = demo.generate()?;
    let (size, flexion) = (demo.size, demo.flexion);
    let dims = size.dims();
    progress.result(&format!(
        "{size:?} phantom {dims:?}, {flexion}° flexion, median of {runs} runs"
    ));
    let pair = (&pair.0, &pair.1);
    let sizes = Sizes::of(pair);
    progress.result(&format!(
        "inputs (source, labels, target as f32): {:.2} MiB; outputs (field, warped, Jacobian, inverse field): {:.2} MiB",
        mib(sizes.inputs),
        mib(sizes.outputs)
    ));
    progress.result(&format!(
        "{:<52} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "backend",
        "init s",
        "adaptive s",
        "compose s",
        "dense s",
        "unfold s",
        "finish s",
        "total s"
    ));
    let mut totals = Vec::new();
    for &kind in kinds {
        let adapter = adapter.clone();
        let (opened, _) = open_backend(&DeviceWanted { kind, adapter })?;
        let timed = crate::on_backend!(opened, backend => time_registrations(backend, runs, pair))?;
        let describe = crate::on_backend!(opened, backend => backend.describe());
        tell_row(&describe, &timed, &sizes, progress);
        tell_memory(&opened, progress);
        totals.push(timed);
    }
    if let [cpu, gpu] = totals.as_slice() {
        tell_ratio(cpu, gpu, progress);
    }
    Ok(())
}

/// One backend's row of the table and its traffic lines.
fn tell_row(describe: &str, timed: &Timed, sizes: &Sizes, progress: &dyn Progress) {
    let t = &timed.stages;
    progress.result(&format!(
        "{describe:<52} {:>10.2} {:>10.2} {:>10.2} {:>10.2} {:>10.2} {:>10.2} {:>10.2}",
        t.initialisation, t.adaptive, t.composition, t.dense, t.unfolding, t.finish, timed.total
    ));
    let stages = &timed.traffic;
    for (stage, traffic) in [
        ("initialisation", stages.initialisation),
        ("adaptive", stages.adaptive),
        ("composition", stages.composition),
        ("dense", stages.dense),
        ("unfolding", stages.unfolding),
        ("finish", stages.finish),
        ("registration", stages.total),
    ] {
        progress.result(&format!(
            "  {stage:<15} up {:>9.2} MiB, down {:>9.2} MiB, {:>7} dispatches, {:>7} submits",
            mib(traffic.bytes_up),
            mib(traffic.bytes_down),
            traffic.dispatches,
            traffic.submits
        ));
    }
    progress.result(&format!(
        "  registration    up {:.2}× its inputs, down {:.2}× its outputs",
        stages.total.bytes_up as f64 / sizes.inputs as f64,
        stages.total.bytes_down as f64 / sizes.outputs as f64
    ));
    let e = &timed.evaluations;
    let per = |v: u64| v as f64 / e.count.max(1) as f64;
    progress.result(&format!(
        "  per evaluation ({} evaluations): up {:.1} KiB, down {:.1} KiB (most {:.1} KiB), {:.1} dispatches, {:.1} submits",
        e.count,
        per(e.traffic.bytes_up) / 1024.0,
        per(e.traffic.bytes_down) / 1024.0,
        e.most_bytes_down as f64 / 1024.0,
        per(e.traffic.dispatches),
        per(e.traffic.submits)
    ));
}

/// The process's peak memory so far and, on a GPU, the largest set of buffers bound at once.
fn tell_memory(opened: &Opened, progress: &dyn Progress) {
    let peak = peak_rss_mib().unwrap_or(f64::NAN);
    progress.result(&match opened {
        Opened::Cpu(_) => format!("  peak host memory (process so far): {peak:.0} MiB"),
        Opened::Gpu(gpu) => format!(
            "  peak host memory (process so far): {peak:.0} MiB; largest set of device buffers bound at once: {:.1} MiB",
            mib(gpu.peak_dispatch_bytes())
        ),
    });
}

/// The GPU's time over the CPU's, per stage and in all.
fn tell_ratio(cpu: &Timed, gpu: &Timed, progress: &dyn Progress) {
    let (c, g) = (&cpu.stages, &gpu.stages);
    let ratio = |g: f64, c: f64| match c > 0.0 {
        true => format!("{:.2}×", g / c),
        false => "–".into(),
    };
    progress.result(&format!(
        "GPU/CPU time: init {}, adaptive {}, dense {}, total {}",
        ratio(g.initialisation, c.initialisation),
        ratio(g.adaptive, c.adaptive),
        ratio(g.dense, c.dense),
        ratio(gpu.total, cpu.total)
    ));
}
