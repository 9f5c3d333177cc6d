//! The backend traits: [`Core`] (buffers and their traffic), one trait per kernel family (in
//! [`sampling`], [`labels`], [`regions`], [`rigid`], [`skinning`], [`dense`], [`fold`],
//! [`correlation`], [`field`], [`reduce`], [`nonrigid`]) and [`Backend`], their sum,
//! implemented by the GPU path (wgpu compute shaders) and its CPU twin (rayon). Host code
//! (registration loops, commands) is written against these traits only, so every stage runs on
//! either and the two can be compared.

pub mod correlation;
pub mod dense;
pub mod field;
pub mod fold;
pub mod labels;
pub mod nonrigid;
pub mod reduce;
pub mod regions;
pub mod rigid;
pub mod sampling;
pub mod skinning;

pub use correlation::box_sums;
pub use nonrigid::CostImages;
pub use reduce::{total, totals};
pub use rigid::BoneImages;
pub use sampling::{resample_onto, resample_volume};

use crate::error::Result;
use crate::volume::{Field, Grid, Image, Labels, Volume};

/// Every backend trait, for code that calls kernels on a concrete backend
/// (`use posereg::backend::prelude::*;`): a method is callable only where its trait is in scope.
pub mod prelude {
    pub use super::correlation::Correlation;
    pub use super::dense::Dense;
    pub use super::field::Fields;
    pub use super::fold::Fold;
    pub use super::labels::LabelMaps;
    pub use super::nonrigid::NonRigid;
    pub use super::reduce::Reduce;
    pub use super::regions::Regions;
    pub use super::rigid::Rigid;
    pub use super::sampling::Sampling;
    pub use super::skinning::Skinning;
    pub use super::{Backend, Core};
}

/// What a backend has moved between the host and the device, and how much work it launched,
/// since it was opened. The CPU backend moves nothing and counts nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Traffic {
    /// Bytes copied from host memory into device buffers (inputs and kernel parameters).
    pub bytes_up: u64,
    /// Bytes copied back from device buffers into host memory.
    pub bytes_down: u64,
    /// Kernel dispatches recorded.
    pub dispatches: u64,
    /// Command submissions to the device's queue (each ends in a blocking wait today).
    pub submits: u64,
}

impl std::ops::Sub for Traffic {
    type Output = Traffic;
    fn sub(self, before: Traffic) -> Traffic {
        Traffic {
            bytes_up: self.bytes_up - before.bytes_up,
            bytes_down: self.bytes_down - before.bytes_down,
            dispatches: self.dispatches - before.dispatches,
            submits: self.submits - before.submits,
        }
    }
}

impl std::ops::AddAssign for Traffic {
    fn add_assign(&mut self, more: Traffic) {
        self.bytes_up += more.bytes_up;
        self.bytes_down += more.bytes_down;
        self.dispatches += more.dispatches;
        self.submits += more.submits;
    }
}

/// Element types a device buffer may hold: f32 for volumes and lattices, f64 where sums of
/// large terms cancel (the cubic RBF, reductions), u32 for voxel indices (lists of voxels:
/// an f32 holds whole numbers exactly only up to 2²⁴).
pub trait Element: bytemuck::Pod + Send + Sync + Into<f64> {
    /// Its WGSL type.
    const WGSL: &'static str;
}
impl Element for f32 {
    const WGSL: &'static str = "f32";
}
impl Element for f64 {
    const WGSL: &'static str = "f64";
}
impl Element for u32 {
    const WGSL: &'static str = "u32";
}

/// An image whose voxels are held where a backend computes; its grid stays on the host. A
/// displacement field is one too, with 3 values per voxel.
pub struct DeviceImage<B: Core> {
    /// Where its voxels are.
    pub grid: Grid,
    /// The values, x fastest (one per voxel, or three for a field).
    pub data: B::Buffer<f32>,
}

impl<B: Core> Clone for DeviceImage<B> {
    /// Shares the voxels (buffers are never written after the kernel that made them).
    fn clone(&self) -> Self {
        DeviceImage {
            grid: self.grid.clone(),
            data: self.data.clone(),
        }
    }
}

impl<B: Core> DeviceImage<B> {
    /// Puts `volume` where `backend` computes (the CPU backend takes it without a copy).
    pub fn upload(backend: &B, what: &str, volume: Volume) -> Result<Self> {
        Ok(DeviceImage {
            data: backend.upload(what, volume.data)?,
            grid: volume.grid,
        })
    }

    /// Puts a label map where `backend` computes, its codes as f32 (exact: codes are u16).
    pub fn upload_labels(backend: &B, labels: &Labels) -> Result<Self> {
        let codes = labels.data.iter().map(|&l| l as f32).collect();
        Ok(DeviceImage {
            data: backend.upload("source labels", codes)?,
            grid: labels.grid.clone(),
        })
    }

    /// Puts a displacement field where `backend` computes.
    pub fn upload_field(backend: &B, what: &str, field: Field) -> Result<Self> {
        Ok(DeviceImage {
            data: backend.upload(what, bytemuck::cast_vec(field.data))?,
            grid: field.grid,
        })
    }

    /// Brings it back to the host.
    pub fn download(&self, backend: &B) -> Result<Volume> {
        Image::from_data(self.grid.clone(), backend.download_one(&self.data)?)
    }

    /// Brings a displacement field back to the host.
    pub fn download_field(&self, backend: &B) -> Result<Field> {
        let values = backend.download_one(&self.data)?;
        Image::from_data(self.grid.clone(), bytemuck::cast_vec(values))
    }
}

/// Where buffers live and how they move: what every kernel family needs.
///
/// Data a registration works on lives where the backend computes, as [`Core::Buffer`]s: a
/// `Vec` on the CPU (nothing is copied), a device buffer on the GPU. Kernel methods that take
/// buffers record work and return buffers or small reductions; the GPU backend submits recorded
/// work only when something is downloaded, so a chain of kernels costs one submission and one
/// wait.
pub trait Core {
    /// An array of `T` held where this backend computes. Buffers are never written after the
    /// kernel (or upload) that made them, so a clone shares one instead of copying it.
    type Buffer<T: Element>: Clone;

    /// One line saying what this backend is (e.g. "gpu: NVIDIA H100 (Vulkan)", "cpu: 2 threads").
    fn describe(&self) -> String;

    /// Everything counted since the backend was opened.
    fn traffic(&self) -> Traffic;

    /// Puts `data` where kernels can read it (`what` names it in errors).
    fn upload<T: Element>(&self, what: &str, data: Vec<T>) -> Result<Self::Buffer<T>>;

    /// Brings `buffers` back to the host, after all work recorded so far, with one wait.
    fn download<T: Element>(&self, buffers: &[&Self::Buffer<T>]) -> Result<Vec<Vec<T>>>;

    /// `len` zeros where kernels can read them, without an upload.
    fn zeros<T: Element>(&self, what: &str, len: usize) -> Result<Self::Buffer<T>>;

    /// A copy of `buffer` where the backend computes, not shared with it: for the kernels
    /// that write a buffer in place (the fold push), which must not change one that others
    /// hold.
    fn duplicate<T: Element>(
        &self,
        what: &str,
        buffer: &Self::Buffer<T>,
    ) -> Result<Self::Buffer<T>>;

    /// Brings one buffer back ([`Core::download`]).
    fn download_one<T: Element>(&self, buffer: &Self::Buffer<T>) -> Result<Vec<T>> {
        Ok(self
            .download(&[buffer])?
            .pop()
            .expect("one buffer asked for"))
    }
}

/// A place kernels run: the core and every kernel family. Host code (registration loops,
/// commands) is written against these traits only, so every stage runs on either backend and
/// the two can be compared. Each backend says it is one (`impl Backend for CpuBackend {}`),
/// and the compiler checks that it has every family.
pub trait Backend:
    Core
    + sampling::Sampling
    + labels::LabelMaps
    + regions::Regions
    + rigid::Rigid
    + skinning::Skinning
    + dense::Dense
    + fold::Fold
    + correlation::Correlation
    + field::Fields
    + reduce::Reduce
    + nonrigid::NonRigid
{
}

/// Checks the grids of two images combined voxel by voxel are the same.
pub fn check_grids(a: &Grid, b: &Grid) -> Result<()> {
    if a.same_as(b, 1e-4) {
        Ok(())
    } else {
        Err(crate::error::Error::InvalidInput(format!(
            "images are on different grids ({:?} vs {:?} voxels, or different affines)",
            a.dims, b.dims
        )))
    }
}
