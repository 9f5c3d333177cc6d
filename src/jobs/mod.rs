//! The jobs the doors offer, whole: files in, outputs written, figures told. Each takes its
//! inputs as paths and settings (the command line's verbs parse their flags into them), calls
//! the registration entry or a stage, writes its outputs atomically into its folder and says
//! what it found through [`crate::progress::Progress`], so that a verb is its arguments and a
//! call, and a second door (a workflow, a GUI) gets the same job with the same outputs.

pub mod bench;
pub mod demo;
pub mod fields;
pub mod initialise;
pub mod outputs;
pub mod points;
pub mod posed;
pub mod register;
pub mod reporter;
pub mod series;
