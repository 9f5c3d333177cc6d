//! How far a long computation has got, and what it has to say. The library reports stages and
//! steps, notes, warnings and result lines through [`Progress`]; the command line draws them as
//! bars on a terminal or log lines elsewhere, and tests pass [`Silent`].

/// Receives a computation's progress. Calls come from the thread that runs the pipeline.
pub trait Progress: Sync {
    /// A stage of `steps` steps begins.
    fn begin(&self, stage: &str, steps: usize);
    /// One step of the current stage is done; `detail` says what it did.
    fn step(&self, detail: &str);
    /// The current stage is over.
    fn end(&self);
    /// An informational line (the device opened, a pose begun), shown unless quiet.
    fn say(&self, line: &str);
    /// Something the user must know about the result, shown even when quiet.
    fn warn(&self, warning: &str);
    /// A line of the result (a figure, where the outputs are), the job's answer.
    fn result(&self, line: &str);
    /// Writes what was said so far to `path` (posereg.log beside a job's outputs); a door
    /// that keeps no log writes nothing.
    fn save_log(&self, _path: &std::path::Path) -> crate::error::Result<()> {
        Ok(())
    }
}

/// Reports nothing.
pub struct Silent;

impl Progress for Silent {
    fn begin(&self, _stage: &str, _steps: usize) {}
    fn step(&self, _detail: &str) {}
    fn end(&self) {}
    fn say(&self, _line: &str) {}
    fn warn(&self, _warning: &str) {}
    fn result(&self, _line: &str) {}
}
