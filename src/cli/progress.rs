//! Progress on the command line: a bar per stage when stderr is a terminal, one log line per
//! step when it is not (CI logs, pipes), nothing with --quiet.

use indicatif::{ProgressBar, ProgressStyle};
use posereg::progress::Progress;
use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::Instant;

/// How progress is shown.
enum Mode {
    Bars,
    Lines,
    Quiet,
}

/// The current stage.
struct Stage {
    name: String,
    steps: usize,
    done: usize,
    started: Instant,
    bar: Option<ProgressBar>,
}

/// Draws a library computation's progress on stderr.
pub struct Reporter {
    mode: Mode,
    stage: Mutex<Option<Stage>>,
}

impl Reporter {
    /// Bars on a terminal, lines elsewhere, nothing when `quiet`.
    pub fn new(quiet: bool) -> Self {
        let mode = if quiet {
            Mode::Quiet
        } else if std::io::stderr().is_terminal() {
            Mode::Bars
        } else {
            Mode::Lines
        };
        Reporter {
            mode,
            stage: Mutex::new(None),
        }
    }

    /// Prints an informational line unless quiet (the device line, notes).
    pub fn say(&self, line: &str) {
        if !matches!(self.mode, Mode::Quiet) {
            eprintln!("{line}");
        }
    }

    /// Prints a warning, even when quiet: something the user must know about the result.
    pub fn warn(&self, line: &str) {
        eprintln!("posereg: warning: {line}");
    }

    fn with_stage(&self, f: impl FnOnce(&mut Option<Stage>)) {
        // A poisoned lock only means another thread panicked while drawing; keep drawing.
        let mut stage = self.stage.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut stage);
    }
}

impl Progress for Reporter {
    fn begin(&self, stage: &str, steps: usize) {
        let bar = match self.mode {
            Mode::Quiet => return,
            Mode::Bars => {
                let bar = ProgressBar::new(steps as u64).with_prefix(stage.to_string());
                if let Ok(style) = ProgressStyle::with_template(
                    "{prefix:>26} [{bar:30}] {pos}/{len} {elapsed:>4} {wide_msg}",
                ) {
                    bar.set_style(style.progress_chars("=> "));
                }
                bar.tick();
                Some(bar)
            }
            Mode::Lines => {
                eprintln!("{stage}: {steps} steps");
                None
            }
        };
        self.with_stage(|s| {
            *s = Some(Stage {
                name: stage.to_string(),
                steps,
                done: 0,
                started: Instant::now(),
                bar,
            })
        });
    }

    fn step(&self, detail: &str) {
        self.with_stage(|s| {
            let Some(stage) = s.as_mut() else { return };
            stage.done += 1;
            match &stage.bar {
                Some(bar) => {
                    bar.inc(1);
                    bar.set_message(detail.to_string());
                }
                None => eprintln!("{} [{}/{}] {detail}", stage.name, stage.done, stage.steps),
            }
        });
    }

    fn end(&self) {
        self.with_stage(|s| {
            let Some(stage) = s.take() else { return };
            let seconds = stage.started.elapsed().as_secs_f64();
            // The finished bar gives way to the same summary line as off a terminal, so
            // whatever prints next starts on a line of its own.
            if let Some(bar) = stage.bar {
                bar.finish_and_clear();
            }
            eprintln!("{}: done in {seconds:.1} s", stage.name);
        });
    }
}
