//! The body's bones and joints, measured on the labels and from bone motions: the kinematic
//! chain, point clouds of bones, the knee's flexion axis, anatomical frames, Grood & Suntay
//! joint kinematics, and how far a bone's registered motion is trusted.

pub mod anatomy;
pub mod chain;
pub mod cloud;
pub mod confidence;
pub mod joint;
pub mod kinematics;
