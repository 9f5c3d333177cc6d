//! The GPU backend: wgpu compute shaders, one host file per group of kernels.
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

use crate::abi::{
    EnergyParams, GainParams, RbfGradParams, RbfLatticeParams, SplatParams, SsdParams,
};
use crate::backend::{Backend, Core, CostImages, Element, Traffic};
use crate::error::Result;
use context::GpuContext;
use kernel::Kernel;
use resident::GpuBuffer;

/// The bind group layout of every kernel outside the families with tables of their own, by
/// name (the names of crate::shaders::KERNELS).
const BASE_BINDINGS: &[KernelBindings] = &[
    ("gain_apply", nonrigid::GAIN_BINDINGS),
    ("gain_ratio", nonrigid::GAIN_BINDINGS),
    ("gain_terms", nonrigid::GAIN_TERMS_BINDINGS),
    ("lattice_energy", nonrigid::ENERGY_BINDINGS),
    ("lattice_splat", nonrigid::SPLAT_BINDINGS),
    ("rbf_adjoint", nonrigid::ADJOINT_BINDINGS),
    ("rbf_lattice", nonrigid::LATTICE_BINDINGS),
    ("ssd_cells", nonrigid::SSD_BINDINGS),
    ("warp_cost", nonrigid::COST_BINDINGS),
    ("warp_image", nonrigid::WARP_IMAGE_BINDINGS),
];

/// A kernel's name and bind group layout.
pub type KernelBindings = (&'static str, &'static [kernel::Binding]);

/// Every kernel's bind group layout, by name: the families' tables after the others'.
pub fn bindings() -> impl Iterator<Item = &'static KernelBindings> {
    BASE_BINDINGS
        .iter()
        .chain(sampling::BINDINGS)
        .chain(labels::BINDINGS)
        .chain(regions::BINDINGS)
        .chain(rigid::BINDINGS)
        .chain(skinning::BINDINGS)
        .chain(dense::BINDINGS)
        .chain(fold::BINDINGS)
        .chain(correlation::BINDINGS)
        .chain(field::BINDINGS)
        .chain(reduce::BINDINGS)
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
    /// shaders/ssd_cells.wgsl
    pub ssd_cells: Kernel,
    /// shaders/warp_image.wgsl
    pub warp_image: Kernel,
    /// shaders/gain_terms.wgsl
    pub gain_terms: Kernel,
    /// shaders/gain_ratio.wgsl
    pub gain_ratio: Kernel,
    /// shaders/gain_apply.wgsl
    pub gain_apply: Kernel,
    /// shaders/lattice_splat.wgsl
    pub lattice_splat: Kernel,
    /// shaders/rbf_lattice.wgsl
    pub rbf_lattice: Kernel,
    /// shaders/warp_cost.wgsl
    pub warp_cost: Kernel,
    /// shaders/lattice_energy.wgsl
    pub lattice_energy: Kernel,
    /// shaders/rbf_adjoint.wgsl
    pub rbf_adjoint: Kernel,
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
}

/// The GPU backend with its compiled kernels.
pub struct GpuBackend {
    ctx: GpuContext,
    /// The compiled kernels.
    pub kernels: Kernels,
    peak_dispatch_bytes: std::sync::atomic::AtomicU64,
    /// Work recorded and not yet submitted (see resident.rs).
    pending: std::sync::Mutex<Option<wgpu::CommandEncoder>>,
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
                ssd_cells: compile(&ctx, "ssd_cells")?,
                warp_image: compile(&ctx, "warp_image")?,
                gain_terms: compile(&ctx, "gain_terms")?,
                gain_ratio: compile(&ctx, "gain_ratio")?,
                gain_apply: compile(&ctx, "gain_apply")?,
                lattice_splat: compile(&ctx, "lattice_splat")?,
                rbf_lattice: compile(&ctx, "rbf_lattice")?,
                warp_cost: compile(&ctx, "warp_cost")?,
                lattice_energy: compile(&ctx, "lattice_energy")?,
                rbf_adjoint: compile(&ctx, "rbf_adjoint")?,
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
            },
            ctx,
            peak_dispatch_bytes: Default::default(),
            pending: Default::default(),
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

    fn zeros(&self, what: &str, len: usize) -> Result<GpuBuffer<f32>> {
        // wgpu fills new buffers with zeros: nothing to upload.
        self.output_buffer(what, len)
    }
}

impl Backend for GpuBackend {
    fn ssd_cells(
        &self,
        params: &SsdParams,
        images: &CostImages<GpuBuffer<f32>>,
    ) -> Result<GpuBuffer<f32>> {
        self.record_ssd_cells(params, images)
    }

    fn warp_image(
        &self,
        params: &RbfGradParams,
        lattice: &GpuBuffer<f32>,
        moving: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        self.record_warp_image(params, lattice, moving)
    }

    fn gain_terms(
        &self,
        params: &GainParams,
        warped: &GpuBuffer<f32>,
        target: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        self.record_gain_terms(params, warped, target)
    }

    fn gain_ratio(
        &self,
        params: &GainParams,
        product: &GpuBuffer<f32>,
        energy: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        self.record_gain_ratio(params, product, energy)
    }

    fn gain_apply(
        &self,
        params: &GainParams,
        gain: &GpuBuffer<f32>,
        moving: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        self.record_gain_apply(params, gain, moving)
    }

    fn rbf_lattice(
        &self,
        params: &RbfLatticeParams,
        geometry: &GpuBuffer<f64>,
        spline: &GpuBuffer<f64>,
    ) -> Result<GpuBuffer<f32>> {
        self.record_rbf_lattice(params, geometry, spline)
    }

    fn warp_cost(
        &self,
        params: &RbfGradParams,
        lattice: &GpuBuffer<f32>,
        images: &CostImages<GpuBuffer<f32>>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        self.record_warp_cost(params, lattice, images)
    }

    fn lattice_splat(
        &self,
        params: &SplatParams,
        values: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        self.record_lattice_splat(params, values)
    }

    fn lattice_energy(
        &self,
        params: &EnergyParams,
        lattice: &GpuBuffer<f32>,
        splat: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        self.record_lattice_energy(params, lattice, splat)
    }

    fn rbf_adjoint(
        &self,
        params: &RbfLatticeParams,
        geometry: &GpuBuffer<f64>,
        spline: &GpuBuffer<f64>,
        node_gradient: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f64>> {
        self.record_rbf_adjoint(params, geometry, spline, node_gradient)
    }
}
