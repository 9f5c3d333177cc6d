//! The GPU backend: wgpu compute shaders, one host file per kernel.
//!
//! Kernels on resident buffers (resident.rs: the pyramid, the rigid, non-rigid and gain kernels)
//! bind whole volumes; one that does not fit the device's binding limit gets a clear error
//! naming the size and the limit. The kernels still called on host volumes (resample, jacobian,
//! skinning, warp_field, compose: run.rs) upload them in slabs of whole z-slices, so no binding
//! exceeds `max_storage_buffer_binding_size` and no dispatch exceeds 65535 workgroups per
//! dimension.

pub mod buffer;
pub mod context;
pub mod field;
pub mod jacobian;
pub mod kernel;
pub mod nonrigid;
pub mod pyramid;
pub mod resample;
pub mod resident;
pub mod rigid;
pub mod run;
pub mod skinning;

use crate::abi::{
    BoneBlend, ComposeParams, EnergyParams, GainParams, Interpolation, JacobianParams,
    PyramidParams, RbfGradParams, RbfLatticeParams, ResampleParams, RigidParams, ScoreParams,
    SkinBlendParams, SkinWeightsParams, SplatParams, SsdParams, SumParams,
};
use crate::backend::{check_pair, Backend, BoneImages, CostImages, Element, Traffic};
use crate::error::{Error, Result};
use crate::volume::{Field, Grid, Image, Volume};
use context::GpuContext;
use kernel::Kernel;
use resident::GpuBuffer;

/// A run of whole slices z0 .. z0 + depth processed in one dispatch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slab {
    /// First slice.
    pub z0: usize,
    /// Number of slices.
    pub depth: usize,
}

/// The bind group layout of every kernel, by name (the names of crate::shaders::KERNELS).
pub const BINDINGS: &[(&str, &[kernel::Binding])] = &[
    ("compose", field::COMPOSE_BINDINGS),
    ("gain_apply", nonrigid::GAIN_BINDINGS),
    ("gain_ratio", nonrigid::GAIN_BINDINGS),
    ("gain_terms", nonrigid::GAIN_TERMS_BINDINGS),
    ("jacobian", jacobian::BINDINGS),
    ("lattice_energy", nonrigid::ENERGY_BINDINGS),
    ("lattice_splat", nonrigid::SPLAT_BINDINGS),
    ("pyramid", pyramid::BINDINGS),
    ("rbf_adjoint", nonrigid::ADJOINT_BINDINGS),
    ("rbf_lattice", nonrigid::LATTICE_BINDINGS),
    ("resample", resample::BINDINGS),
    ("rigid_gn", rigid::GN_BINDINGS),
    ("rigid_score", rigid::SCORE_BINDINGS),
    ("skin_blend", skinning::BLEND_BINDINGS),
    ("skin_weights", skinning::WEIGHTS_BINDINGS),
    ("ssd_cells", nonrigid::SSD_BINDINGS),
    ("sum_chunks", nonrigid::SUM_BINDINGS),
    ("sum_partials", nonrigid::PARTIALS_BINDINGS),
    ("sum_partials_f32", nonrigid::PARTIALS_BINDINGS),
    ("warp_cost", nonrigid::COST_BINDINGS),
    ("warp_field", field::WARP_BINDINGS),
    ("warp_image", nonrigid::WARP_IMAGE_BINDINGS),
];

fn compile(ctx: &GpuContext, name: &'static str) -> Result<Kernel> {
    let bindings = BINDINGS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, b)| *b)
        .unwrap_or_else(|| panic!("kernel {name} has no bindings entry"));
    Kernel::new(ctx, name, bindings)
}

/// Every compiled kernel.
pub struct Kernels {
    /// shaders/resample.wgsl
    pub resample: Kernel,
    /// shaders/ssd_cells.wgsl
    pub ssd_cells: Kernel,
    /// shaders/jacobian.wgsl
    pub jacobian: Kernel,
    /// shaders/pyramid.wgsl
    pub pyramid: Kernel,
    /// shaders/rigid_gn.wgsl
    pub rigid_gn: Kernel,
    /// shaders/rigid_score.wgsl
    pub rigid_score: Kernel,
    /// shaders/skin_weights.wgsl
    pub skin_weights: Kernel,
    /// shaders/skin_blend.wgsl
    pub skin_blend: Kernel,
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
    /// shaders/sum_chunks.wgsl
    pub sum_chunks: Kernel,
    /// shaders/sum_partials.wgsl over f64 partials
    pub sum_partials: Kernel,
    /// shaders/sum_partials.wgsl over f32 partials
    pub sum_partials_f32: Kernel,
    /// shaders/warp_field.wgsl
    pub warp_field: Kernel,
    /// shaders/compose.wgsl
    pub compose: Kernel,
}

/// The GPU backend with its compiled kernels.
pub struct GpuBackend {
    ctx: GpuContext,
    /// The compiled kernels.
    pub kernels: Kernels,
    max_slab_voxels: Option<usize>,
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
                resample: compile(&ctx, "resample")?,
                ssd_cells: compile(&ctx, "ssd_cells")?,
                jacobian: compile(&ctx, "jacobian")?,
                pyramid: compile(&ctx, "pyramid")?,
                rigid_gn: compile(&ctx, "rigid_gn")?,
                rigid_score: compile(&ctx, "rigid_score")?,
                skin_weights: compile(&ctx, "skin_weights")?,
                skin_blend: compile(&ctx, "skin_blend")?,
                warp_image: compile(&ctx, "warp_image")?,
                gain_terms: compile(&ctx, "gain_terms")?,
                gain_ratio: compile(&ctx, "gain_ratio")?,
                gain_apply: compile(&ctx, "gain_apply")?,
                lattice_splat: compile(&ctx, "lattice_splat")?,
                rbf_lattice: compile(&ctx, "rbf_lattice")?,
                warp_cost: compile(&ctx, "warp_cost")?,
                lattice_energy: compile(&ctx, "lattice_energy")?,
                rbf_adjoint: compile(&ctx, "rbf_adjoint")?,
                sum_chunks: compile(&ctx, "sum_chunks")?,
                sum_partials: compile(&ctx, "sum_partials")?,
                sum_partials_f32: compile(&ctx, "sum_partials_f32")?,
                warp_field: compile(&ctx, "warp_field")?,
                compose: compile(&ctx, "compose")?,
            },
            ctx,
            max_slab_voxels: None,
            peak_dispatch_bytes: Default::default(),
            pending: Default::default(),
        })
    }

    /// Caps the voxels per slab below what the device limits allow (for tests of the slab
    /// path, and to bound peak device memory).
    pub fn with_max_slab_voxels(mut self, voxels: usize) -> Self {
        self.max_slab_voxels = Some(voxels.max(1));
        self
    }

    /// The device this backend runs on.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// Largest total of buffer bytes bound to one dispatch so far: the device memory a
    /// registration needs at once (buffers are released after each call).
    pub fn peak_dispatch_bytes(&self) -> u64 {
        self.peak_dispatch_bytes
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Records the bytes bound to one dispatch.
    pub(crate) fn note_dispatch_bytes(&self, bytes: u64) {
        self.peak_dispatch_bytes
            .fetch_max(bytes, std::sync::atomic::Ordering::Relaxed);
    }

    /// Splits `dims` into slabs whose per-voxel buffers (`bytes_per_voxel` for the largest,
    /// holding the slab plus `halo` extra slices) fit the device's binding limits, the optional
    /// cap, and the workgroup count limit.
    pub fn plan_slabs(
        &self,
        dims: [usize; 3],
        bytes_per_voxel: usize,
        halo: usize,
    ) -> Result<Vec<Slab>> {
        let slice = dims[0] * dims[1];
        let limit = self
            .ctx
            .limits
            .max_storage_buffer_binding_size
            .min(self.ctx.limits.max_buffer_size);
        let fits = (limit / bytes_per_voxel as u64) as usize;
        if slice * (1 + halo) > fits {
            return Err(Error::DeviceLimit {
                what: format!("one {}×{} slice", dims[0], dims[1]),
                needed: (slice * bytes_per_voxel) as u64,
                limit,
                limit_name: "max_storage_buffer_binding_size",
            });
        }
        let cap = self.max_slab_voxels.unwrap_or(usize::MAX).min(fits);
        let max_depth = (cap / slice)
            .saturating_sub(halo)
            .max(1)
            .min(self.ctx.limits.max_compute_workgroups_per_dimension as usize);
        Ok((0..dims[2])
            .step_by(max_depth)
            .map(|z0| Slab {
                z0,
                depth: max_depth.min(dims[2] - z0),
            })
            .collect())
    }
}

impl Backend for GpuBackend {
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

    fn resample(
        &self,
        source: &Volume,
        field: &Field,
        background: f32,
        interpolation: Interpolation,
    ) -> Result<Volume> {
        let params = ResampleParams::new(&source.grid, &field.grid, background, interpolation);
        let data = resample::resample(
            self,
            &params,
            &source.data,
            bytemuck::cast_slice(&field.data),
        )?;
        Image::from_data(field.grid.clone(), data)
    }

    fn ssd_cells(
        &self,
        params: &SsdParams,
        images: &CostImages<GpuBuffer<f32>>,
    ) -> Result<GpuBuffer<f32>> {
        self.record_ssd_cells(params, images)
    }

    fn jacobian(&self, field: &Field) -> Result<Volume> {
        let params = JacobianParams::new(&field.grid);
        let data = jacobian::jacobian(self, &params, bytemuck::cast_slice(&field.data))?;
        Image::from_data(field.grid.clone(), data)
    }

    fn pyramid_level(
        &self,
        params: &PyramidParams,
        input: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        self.record_pyramid(params, input)
    }

    fn rigid_sums(
        &self,
        params: &RigidParams,
        images: &BoneImages<GpuBuffer<f32>>,
    ) -> Result<GpuBuffer<f32>> {
        self.record_rigid_sums(params, images)
    }

    fn rigid_scores(
        &self,
        params: &ScoreParams,
        images: &BoneImages<GpuBuffer<f32>>,
        candidates: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        self.record_rigid_scores(params, images, candidates)
    }

    fn skin_weights(
        &self,
        distances: &[f32],
        grid: &Grid,
        bones: usize,
        power: u32,
    ) -> Result<Vec<f32>> {
        skinning::skin_weights(self, &SkinWeightsParams::new(grid, bones, power), distances)
    }

    fn skin_blend(
        &self,
        weights: &[f32],
        weight_grid: &Grid,
        bone_of_voxel: &[f32],
        labels: &Grid,
        target: &Grid,
        blend: &BoneBlend,
    ) -> Result<Vec<f32>> {
        crate::abi::check_bone_count(blend.motions.len())?;
        let params = SkinBlendParams::new(target, weight_grid, labels, blend);
        skinning::skin_blend(self, &params, weights, bone_of_voxel)
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

    fn warp_field(
        &self,
        lattice: &[f32],
        lattice_dims: [usize; 3],
        step: usize,
        grid: &Grid,
    ) -> Result<Field> {
        let params = RbfGradParams::new(grid, lattice_dims, step);
        let out = field::warp_field(self, &params, lattice)?;
        Image::from_data(grid.clone(), bytemuck::cast_slice(&out).to_vec())
    }

    fn compose(&self, warp: &Field, initial: &Field) -> Result<Field> {
        check_pair(warp, initial)?;
        let params = ComposeParams::new(&warp.grid);
        let out = field::compose(
            self,
            &params,
            bytemuck::cast_slice(&warp.data),
            bytemuck::cast_slice(&initial.data),
        )?;
        Image::from_data(warp.grid.clone(), bytemuck::cast_slice(&out).to_vec())
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

    fn sum_partials<T: Element>(
        &self,
        partials: &GpuBuffer<T>,
        values: usize,
    ) -> Result<GpuBuffer<f64>> {
        self.record_sum_partials(partials, values)
    }

    fn sum_chunks(&self, params: &SumParams, values: &GpuBuffer<f32>) -> Result<GpuBuffer<f64>> {
        self.record_sum_chunks(params, values)
    }
}
