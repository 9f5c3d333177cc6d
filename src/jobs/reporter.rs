//! Progress shown to a person (the command line, the Python package with `progress=True`): a
//! bar per stage when stderr is a terminal, one log line per step when it is not (CI logs,
//! pipes, notebooks' captured output), nothing when quiet. Every line, quiet or not, is
//! also kept with its time for the log a verb writes beside its outputs (posereg.log) once
//! they are written: a failed run leaves no half-written folder, its error is on stderr.

use crate::progress::Progress;
use indicatif::{ProgressBar, ProgressStyle};
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

/// Draws a library computation's progress on stderr and keeps the log.
pub struct Reporter {
    mode: Mode,
    stage: Mutex<Option<Stage>>,
    started: Instant,
    log: Mutex<Vec<String>>,
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
            started: Instant::now(),
            log: Mutex::new(Vec::new()),
        }
    }

    /// Keeps `line` for the log, stamped with the seconds since the start.
    fn keep(&self, line: &str) {
        let at = self.started.elapsed().as_secs_f64();
        let mut log = self.log.lock().unwrap_or_else(|e| e.into_inner());
        log.push(format!("[{at:8.2} s] {line}"));
    }

    fn with_stage(&self, f: impl FnOnce(&mut Option<Stage>)) {
        // A poisoned lock only means another thread panicked while drawing; keep drawing.
        let mut stage = self.stage.lock().unwrap_or_else(|e| e.into_inner());
        f(&mut stage);
    }
}

impl Progress for Reporter {
    fn begin(&self, stage: &str, steps: usize) {
        let line = format!("{stage}: {steps} steps");
        self.keep(&line);
        let bar = match self.mode {
            Mode::Quiet => None,
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
                eprintln!("{line}");
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
            let line = format!("{} [{}/{}] {detail}", stage.name, stage.done, stage.steps);
            self.keep(&line);
            match (&stage.bar, &self.mode) {
                (Some(bar), _) => {
                    bar.inc(1);
                    bar.set_message(detail.to_string());
                }
                (None, Mode::Lines) => eprintln!("{line}"),
                (None, _) => {}
            }
        });
    }

    fn end(&self) {
        self.with_stage(|s| {
            let Some(stage) = s.take() else { return };
            let seconds = stage.started.elapsed().as_secs_f64();
            let line = format!("{}: done in {seconds:.1} s", stage.name);
            self.keep(&line);
            // The finished bar gives way to the same summary line as off a terminal, so
            // whatever prints next starts on a line of its own.
            if let Some(bar) = stage.bar {
                bar.finish_and_clear();
            }
            if !matches!(self.mode, Mode::Quiet) {
                eprintln!("{line}");
            }
        });
    }

    /// Prints an informational line unless quiet (the device line, notes).
    fn say(&self, line: &str) {
        self.keep(line);
        if !matches!(self.mode, Mode::Quiet) {
            eprintln!("{line}");
        }
    }

    /// Prints a warning, even when quiet: something the user must know about the result.
    fn warn(&self, line: &str) {
        let line = format!("posereg: warning: {line}");
        self.keep(&line);
        eprintln!("{line}");
    }

    /// Prints the verb's result on stdout.
    fn result(&self, line: &str) {
        self.keep(line);
        println!("{line}");
    }

    /// Writes the log so far, with the command line, to `path`.
    fn save_log(&self, path: &std::path::Path) -> crate::error::Result<()> {
        let command: Vec<String> = std::env::args().collect();
        let lines = self.log.lock().unwrap_or_else(|e| e.into_inner());
        let text = format!(
            "posereg {}: {}\n{}\n",
            env!("CARGO_PKG_VERSION"),
            command.join(" "),
            lines.join("\n")
        );
        crate::io::write_bytes(path, text)
    }
}
