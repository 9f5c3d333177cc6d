//! Whole registrations: inputs loaded and checked, one pair registered (initialisation,
//! non-rigid stage, composition, fold check, resampling), pose series through their neighbours.

pub mod bench;
pub mod inputs;
pub mod options;
pub mod register;
pub mod series;
