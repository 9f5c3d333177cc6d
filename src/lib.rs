//! # posereg
//!
//! Registration of 3-D MRI of an articulated body across poses (a straight knee onto the same
//! knee bent), after Rhee et al., "Adaptive non-rigid registration of 3D knee MRI in different
//! pose spaces": per-bone rigid registration, volume skeletal deformation (linear blend
//! skinning of the whole volume) as initialisation, then adaptive non-rigid registration with
//! sparse cubic radial-basis control points. The paper calls φ(r) = r³ a "thin plate spline";
//! in 3-D it is the cubic (triharmonic) radial basis, which elastix calls VolumeSpline; the code
//! says `rbf`/cubic.
//!
//! ## Shape
//! Per-voxel work is done by kernels, each written twice: a WGSL compute shader
//! (`shaders/`, run through wgpu by [`gpu::GpuBackend`]) and a CPU twin (`cpu/`, rayon,
//! [`cpu::CpuBackend`]) that computes the same function in the same f32 order. Host code is
//! generic over [`backend::Backend`]. Parameter structs shared with the shaders are in [`abi`].
//!
//! ## Coordinates
//! Inside the library everything is world millimetres in NIfTI RAS+ (+x Right, +y Anterior,
//! +z Superior), placed by the sform when sform_code > 0, else the qform, else pixdim (the rule
//! nibabel and ITK follow). Voxels are stored x fastest. A displacement field lives on the
//! target grid and maps a target point p to the source point p + u(p). On disk, fields follow
//! the ITK/ANTs convention (LPS vectors); see [`io::field`].

#![warn(missing_docs)]

pub mod abi;
pub mod adaptive;
pub mod anatomy;
pub mod articulated;
pub mod backend;
pub mod chain;
pub mod check;
pub mod cloud;
pub mod confidence;
pub mod cpu;
pub mod device;
pub mod error;
pub mod evaluate;
pub mod fold_repair;
pub mod gain;
pub mod gpu;
pub mod inputs;
pub mod inverse;
pub mod io;
pub mod joint;
pub mod kinematics;
pub mod labels;
pub mod levels;
pub mod metric;
pub mod optim;
pub mod phantom;
pub mod picture;
pub mod points;
pub mod progress;
pub mod pyramid;
pub mod quicklook;
pub mod rbf;
pub mod reach;
pub mod regions;
pub mod register;
pub mod regularise;
pub mod report;
pub mod repose;
pub mod result_checks;
pub mod rigid;
pub mod sample;
pub mod series;
pub mod shaders;
pub mod similarity;
pub mod skinning;
pub mod volume;
pub mod vsd;

pub use backend::Backend;
pub use error::{Error, Result};
pub use volume::{Affine, Field, Grid, Image, Labels, Volume};
