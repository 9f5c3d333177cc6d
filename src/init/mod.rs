//! The articulated initialisation (paper §2): per-bone rigid registration, skinning weights and
//! their reach, volume skeletal deformation; and the same model run forwards to pose a scan
//! (`repose`).

pub mod articulated;
pub mod pins;
pub mod reach;
pub mod repose;
pub mod rigid;
pub mod skinning;
pub mod vsd;
