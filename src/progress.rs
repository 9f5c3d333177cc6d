//! How far a long computation has got. The library reports stages and steps through
//! [`Progress`]; the command line draws them as bars on a terminal or log lines elsewhere, and
//! tests pass [`Silent`].

/// Receives a computation's progress. Calls come from the thread that runs the pipeline.
pub trait Progress: Sync {
    /// A stage of `steps` steps begins.
    fn begin(&self, stage: &str, steps: usize);
    /// One step of the current stage is done; `detail` says what it did.
    fn step(&self, detail: &str);
    /// The current stage is over.
    fn end(&self);
}

/// Reports nothing.
pub struct Silent;

impl Progress for Silent {
    fn begin(&self, _stage: &str, _steps: usize) {}
    fn step(&self, _detail: &str) {}
    fn end(&self) {}
}
