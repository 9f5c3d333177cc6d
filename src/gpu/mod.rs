//! The GPU backend: wgpu compute shaders, one host file per kernel family.
//!
//! Data stays on the device (resident.rs): every kernel binds whole buffers and records its
//! dispatch into one pending command encoder, submitted when something is downloaded. A
//! buffer beyond the device's binding limit gets a `DeviceLimit` error naming it (buffer.rs),
//! and a dispatch beyond the workgroup limit a clear error (kernel.rs).

pub mod buffer;
pub mod context;
pub mod correlation;
pub mod dense;
pub mod field;
pub mod fold;
pub mod kernel;
pub mod labels;
pub mod nonrigid;
pub mod reduce;
pub mod regions;
pub mod resident;
pub mod rigid;
pub mod sampling;
pub mod skinning;

use crate::backend::{Backend, Core, Element, Traffic};
use crate::error::Result;
use context::GpuContext;
use kernel::Kernel;
use resident::GpuBuffer;

/// A kernel's name and bind group layout.
pub type KernelBindings = (&'static str, &'static [kernel::Binding]);

/// Every kernel's bind group layout, by name: the families' tables one after the other.
pub fn bindings() -> impl Iterator<Item = &'static KernelBindings> {
    sampling::BINDINGS
        .iter()
        .chain(labels::BINDINGS)
        .chain(regions::BINDINGS)
        .chain(rigid::BINDINGS)
        .chain(skinning::BINDINGS)
        .chain(dense::BINDINGS)
        .chain(fold::BINDINGS)
        .chain(correlation::BINDINGS)
        .chain(field::BINDINGS)
        .chain(reduce::BINDINGS)
        .chain(nonrigid::BINDINGS)
}

fn compile(ctx: &GpuContext, name: &'static str) -> Result<Kernel> {
    let bindings = bindings()
        .find(|(n, _)| *n == name)
        .map(|(_, b)| *b)
        .unwrap_or_else(|| panic!("kernel {name} has no bindings entry"));
    Kernel::new(ctx, name, bindings)
}

/// Every compiled kernel.
pub struct Kernels {
    /// The sampling family (shaders/sampling/).
    pub sampling: sampling::SamplingKernels,
    /// The label family (shaders/labels/).
    pub labels: labels::LabelKernels,
    /// The regions family (shaders/regions/).
    pub regions: regions::RegionsKernels,
    /// The rigid family (shaders/rigid/).
    pub rigid: rigid::RigidKernels,
    /// The skinning family (shaders/skinning/).
    pub skinning: skinning::SkinningKernels,
    /// The dense stage's family (shaders/dense/).
    pub dense: dense::DenseKernels,
    /// The fold family (shaders/fold/).
    pub fold: fold::FoldKernels,
    /// The correlation family (shaders/correlation/).
    pub correlation: correlation::CorrelationKernels,
    /// The field family (shaders/field/).
    pub field: field::FieldKernels,
    /// The reduce family (shaders/reduce/).
    pub reduce: reduce::ReduceKernels,
    /// The non-rigid family (shaders/nonrigid/).
    pub nonrigid: nonrigid::NonRigidKernels,
}

/// The GPU backend with its compiled kernels.
pub struct GpuBackend {
    ctx: GpuContext,
    /// The compiled kernels.
    pub kernels: Kernels,
    peak_dispatch_bytes: std::sync::atomic::AtomicU64,
    /// Work recorded and not yet submitted (see resident.rs).
    pending: std::sync::Mutex<Option<wgpu::CommandEncoder>>,
    /// Uniform buffers made so far, by their bytes (see resident.rs).
    uniforms: std::sync::Mutex<std::collections::HashMap<Vec<u8>, wgpu::Buffer>>,
}

impl GpuBackend {
    /// Opens the adapter (see [`GpuContext::new`]) and compiles every kernel.
    pub fn new() -> Result<Self> {
        Self::with_context(GpuContext::new()?)
    }

    /// Compiles every kernel on an opened context.
    pub fn with_context(ctx: GpuContext) -> Result<Self> {
        Ok(GpuBackend {
            kernels: Kernels {
                sampling: sampling::SamplingKernels::new(&ctx)?,
                labels: labels::LabelKernels::new(&ctx)?,
                regions: regions::RegionsKernels::new(&ctx)?,
                rigid: rigid::RigidKernels::new(&ctx)?,
                skinning: skinning::SkinningKernels::new(&ctx)?,
                dense: dense::DenseKernels::new(&ctx)?,
                fold: fold::FoldKernels::new(&ctx)?,
                correlation: correlation::CorrelationKernels::new(&ctx)?,
                field: field::FieldKernels::new(&ctx)?,
                reduce: reduce::ReduceKernels::new(&ctx)?,
                nonrigid: nonrigid::NonRigidKernels::new(&ctx)?,
            },
            ctx,
            peak_dispatch_bytes: Default::default(),
            pending: Default::default(),
            uniforms: Default::default(),
        })
    }

    /// The device this backend runs on.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Largest total of buffer bytes bound to one dispatch so far: a lower bound on the device
    /// memory a registration needs at once.
    pub fn peak_dispatch_bytes(&self) -> u64 {
        self.peak_dispatch_bytes
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Records the bytes bound to one dispatch.
    pub(crate) fn note_dispatch_bytes(&self, bytes: u64) {
        self.peak_dispatch_bytes
            .fetch_max(bytes, std::sync::atomic::Ordering::Relaxed);
    }
}

impl Backend for GpuBackend {}

impl Core for GpuBackend {
    type Buffer<T: Element> = GpuBuffer<T>;

    fn upload<T: Element>(&self, what: &str, data: Vec<T>) -> Result<GpuBuffer<T>> {
        self.upload_buffer(what, &data)
    }

    fn download<T: Element>(&self, buffers: &[&GpuBuffer<T>]) -> Result<Vec<Vec<T>>> {
        self.download_buffers(buffers)
    }

    fn describe(&self) -> String {
        format!("gpu: {}", self.ctx.describe())
    }

    fn traffic(&self) -> Traffic {
        self.ctx.counters.read()
    }

    fn zeros<T: Element>(&self, what: &str, len: usize) -> Result<GpuBuffer<T>> {
        // wgpu fills new buffers with zeros: nothing to upload.
        self.output_buffer(what, len)
    }

    fn duplicate<T: Element>(&self, what: &str, buffer: &GpuBuffer<T>) -> Result<GpuBuffer<T>> {
        let copy = self.output_buffer(what, buffer.len())?;
        self.record_copy(buffer, &copy)?;
        Ok(copy)
    }
}
