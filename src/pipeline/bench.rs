//! What `posereg bench` measures: whole registrations of a phantom pair on one backend with the
//! default settings, each stage's median seconds over the runs, the host↔device traffic of each
//! stage and of each adaptive evaluation, and the bytes of the inputs and outputs that traffic
//! is compared with. The command line prints it.

use crate::backend::Backend;
use crate::error::Result;
use crate::nonrigid::adaptive::Evaluations;
use crate::phantom::Phantom;
use crate::pipeline::register::{register, Inputs, RegisterOptions, StageTimes, StageTraffic};
use crate::progress::Silent;

/// A backend's registrations of one pair, timed.
pub struct Timed {
    /// Each stage's median seconds.
    pub stages: StageTimes,
    /// The median of the whole registrations' seconds.
    pub total: f64,
    /// The traffic of the last run (the same every run: the work is deterministic).
    pub traffic: StageTraffic,
    /// The adaptive stage's evaluations in the last run.
    pub evaluations: Evaluations,
}

/// Registers `pair` (source, target) `runs` times on `backend`.
pub fn time_registrations<B: Backend>(
    backend: &B,
    runs: u64,
    pair: (&Phantom, &Phantom),
) -> Result<Timed> {
    let mut all: Vec<StageTimes> = Vec::new();
    let mut traffic = StageTraffic::default();
    let mut evaluations = Evaluations::default();
    for _ in 0..runs {
        let inputs = Inputs::new(&pair.0.image, &pair.0.labels, &pair.1.image);
        let r = register(backend, inputs, &RegisterOptions::default(), &Silent)?;
        all.push(r.timings);
        (traffic, evaluations) = (r.traffic, r.adaptive.evaluations);
    }
    let m = |f: fn(&StageTimes) -> f64| median(all.iter().map(f).collect());
    Ok(Timed {
        stages: StageTimes {
            initialisation: m(|t| t.initialisation),
            adaptive: m(|t| t.adaptive),
            composition: m(|t| t.composition),
            dense: m(|t| t.dense),
            unfolding: m(|t| t.unfolding),
            finish: m(|t| t.finish),
        },
        total: m(StageTimes::total),
        traffic,
        evaluations,
    })
}

/// The middle value (the upper one of an even count); NaN for none.
fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Bytes of a registration's input volumes (source, labels, target as f32) and of the volumes it
/// writes (field, warped source and Jacobian on the target's grid; the inverse field on the
/// source's).
pub struct Sizes {
    /// Source, labels and target, as f32.
    pub inputs: u64,
    /// Field, warped source, Jacobian and inverse field.
    pub outputs: u64,
}

impl Sizes {
    /// Of the pair (source, target).
    pub fn of(pair: (&Phantom, &Phantom)) -> Self {
        let (source, target) = (
            pair.0.image.grid.len() as u64,
            pair.1.image.grid.len() as u64,
        );
        Sizes {
            inputs: 4 * (2 * source + target),
            outputs: 20 * target + 12 * source,
        }
    }
}

/// Peak resident memory of this process so far (Linux), in MiB.
pub fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn the_median_is_the_middle_value() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), 3.0);
        assert!(median(Vec::new()).is_nan());
    }
}
