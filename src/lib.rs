//! # posereg
//!
//! Registration of 3-D MRI of an articulated body across poses (a straight knee onto the same
//! knee bent), after Rhee et al., "Adaptive non-rigid registration of 3D knee MRI in different
//! pose spaces": per-bone rigid registration, volume skeletal deformation (linear blend
//! skinning of the whole volume) as initialisation, then adaptive non-rigid registration with
//! sparse cubic radial-basis control points; beyond the paper, a dense refinement (a
//! stationary velocity field held off the bones) follows what sparse points cannot. The paper
//! calls φ(r) = r³ a "thin plate spline"; in 3-D it is the cubic (triharmonic) radial basis,
//! which elastix calls VolumeSpline; the code says `rbf`/cubic.
//!
//! ## Shape
//! Per-voxel work is done by kernels, each written twice: a WGSL compute shader
//! (`shaders/`, run through wgpu by [`gpu::GpuBackend`]) and a CPU twin (`cpu/`, rayon,
//! [`cpu::CpuBackend`]) that computes the same function in the same f32 order. Host code is
//! generic over [`backend::Backend`]. Parameter structs shared with the shaders are in [`abi`].
//!
//! ## Layout, bottom up
//! A module imports only from the layers below its own and from its own group (tests/layers.rs
//! checks this):
//! - the kernel vocabulary: [`abi`], [`backend`], [`volume`], [`error`], [`labels`], [`levels`],
//!   [`check`], [`progress`], [`sample`], [`shaders`];
//! - the two backends, [`cpu`] and [`gpu`], and [`device`], which chooses between them;
//! - operations the stages share: [`images`] (pyramids, regions, fold repair, the inverse field,
//!   similarity measures) and [`joints`] (the kinematic chain, frames, joint kinematics);
//! - files on disk: [`io`];
//! - the stages: [`init`] (per-bone rigid, skinning, volume skeletal deformation) and
//!   [`nonrigid`] (the adaptive RBF stage), and the analytic [`phantom`];
//! - whole registrations: [`pipeline`]; what they are reported by: [`report`];
//! - the command line (the binary's `cli` module).
//!
//! ## Coordinates
//! Inside the library everything is world millimetres in NIfTI RAS+ (+x Right, +y Anterior,
//! +z Superior), placed by the sform when sform_code > 0, else the qform, else pixdim (the rule
//! nibabel and ITK follow). Voxels are stored x fastest. A displacement field lives on the
//! target grid and maps a target point p to the source point p + u(p). On disk, fields follow
//! the ITK/ANTs convention (LPS vectors); see [`io::field`].

#![warn(missing_docs)]

pub mod abi;
pub mod backend;
pub mod check;
pub mod cpu;
pub mod device;
pub mod error;
pub mod finish;
pub mod gpu;
pub mod images;
pub mod init;
pub mod io;
pub mod jobs;
pub mod joints;
pub mod labels;
pub mod levels;
pub mod nonrigid;
pub mod phantom;
pub mod pipeline;
pub mod progress;
pub mod registration;
pub mod report;
pub mod sample;
pub mod shaders;
pub mod volume;

pub use backend::Backend;
pub use error::{Error, Result};
pub use volume::{Affine, Field, Grid, Image, Labels, Volume};
