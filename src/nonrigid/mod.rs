//! The adaptive non-rigid stage (paper §3): cubic radial-basis control points placed where the
//! fit is poor, coarse to fine, their warp, the intensity gain, the smoothness energies and the
//! L-BFGS minimiser; and the dense refinement after it (beyond the paper).

pub mod adaptive;
pub mod dense;
pub mod gain;
pub mod optim;
pub mod rbf;
pub mod regularise;
