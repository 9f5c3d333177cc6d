//! The adaptive non-rigid stage (paper §3): cubic radial-basis control points placed where the
//! fit is poor, coarse to fine, their warp, the intensity gain, the smoothness energies and the
//! L-BFGS minimiser.

pub mod adaptive;
pub mod gain;
pub mod optim;
pub mod rbf;
pub mod regularise;
