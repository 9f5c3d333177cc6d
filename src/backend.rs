//! The `Backend` trait: one method per kernel, implemented by the GPU path (wgpu compute
//! shaders) and its CPU twin (rayon). Host code (registration loops, commands) is written
//! against this trait only, so every stage runs on either and the two can be compared.

use crate::abi::{
    BoneBlend, EnergyParams, GainParams, Interpolation, PyramidParams, RbfGradParams,
    RbfLatticeParams, RigidParams, ScoreParams, SplatParams, SsdParams, SumParams,
};
use crate::error::Result;
use crate::volume::{Field, Grid, Image, Volume};

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
/// large terms cancel (the cubic RBF, reductions).
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

/// An image whose voxels are held where a backend computes; its grid stays on the host.
pub struct DeviceImage<B: Backend> {
    /// Where its voxels are.
    pub grid: Grid,
    /// One value per voxel, x fastest.
    pub data: B::Buffer<f32>,
}

impl<B: Backend> DeviceImage<B> {
    /// Puts `volume` where `backend` computes (the CPU backend takes it without a copy).
    pub fn upload(backend: &B, what: &str, volume: Volume) -> Result<Self> {
        Ok(DeviceImage {
            data: backend.upload(what, volume.data)?,
            grid: volume.grid,
        })
    }

    /// Brings it back to the host.
    pub fn download(&self, backend: &B) -> Result<Volume> {
        Image::from_data(self.grid.clone(), backend.download_one(&self.data)?)
    }
}

/// The images one step of a bone's rigid registration compares, at one pyramid level.
pub struct BoneImages<'a, T: ?Sized> {
    /// The source S.
    pub source: &'a T,
    /// The bone's region on the source grid (≥ 0.5 inside).
    pub mask: &'a T,
    /// The target T, sampled through the motion.
    pub target: &'a T,
}

/// The images one evaluation of the non-rigid cost compares, on the target grid.
pub struct CostImages<'a, T: ?Sized> {
    /// I0, sampled through the warp.
    pub moving: &'a T,
    /// The target T.
    pub fixed: &'a T,
    /// c: the share of I0's sample that holds data from the source scan (0 or 1 at the finest
    /// level); kernels count a voxel where c ≥ abi::COVERED_AT.
    pub covered: &'a T,
}

/// A place kernels run.
///
/// Data a registration works on lives where the backend computes, as [`Backend::Buffer`]s: a
/// `Vec` on the CPU (nothing is copied), a device buffer on the GPU. Kernel methods that take
/// buffers record work and return buffers or small reductions; the GPU backend submits recorded
/// work only when something is downloaded, so a chain of kernels costs one submission and one
/// wait.
pub trait Backend {
    /// An array of `T` held where this backend computes.
    type Buffer<T: Element>;

    /// One line saying what this backend is (e.g. "gpu: NVIDIA H100 (Vulkan)", "cpu: 2 threads").
    fn describe(&self) -> String;

    /// Everything counted since the backend was opened.
    fn traffic(&self) -> Traffic;

    /// Puts `data` where kernels can read it (`what` names it in errors).
    fn upload<T: Element>(&self, what: &str, data: Vec<T>) -> Result<Self::Buffer<T>>;

    /// Brings `buffers` back to the host, after all work recorded so far, with one wait.
    fn download<T: Element>(&self, buffers: &[&Self::Buffer<T>]) -> Result<Vec<Vec<T>>>;

    /// Brings one buffer back ([`Backend::download`]).
    fn download_one<T: Element>(&self, buffer: &Self::Buffer<T>) -> Result<Vec<T>> {
        Ok(self
            .download(&[buffer])?
            .pop()
            .expect("one buffer asked for"))
    }

    /// Resampling of `source` at x + u(x) for every voxel x of `field`'s grid (the target
    /// grid), trilinear or nearest; `background` where that point is outside the source.
    fn resample(
        &self,
        source: &Volume,
        field: &Field,
        background: f32,
        interpolation: Interpolation,
    ) -> Result<Volume>;

    /// Per-column partial sums of c (a − b)² per cell (layout of shaders/ssd_cells.wgsl, folded
    /// by metric::fold_ssd_partials): a = `images.moving`, b = `images.fixed`, c = 1 where
    /// `images.covered` says the moving image holds data.
    fn ssd_cells(
        &self,
        params: &SsdParams,
        images: &CostImages<Self::Buffer<f32>>,
    ) -> Result<Self::Buffer<f32>>;

    /// det(I + du/dx) of the map x → x + u(x) at every voxel of the field's grid: where it is
    /// ≤ 0 the map folds.
    fn jacobian(&self, field: &Field) -> Result<Volume>;

    /// One pyramid step: a level smoothed and decimated (see pyramid::next_level_grid) as
    /// `params` says.
    fn pyramid_level(
        &self,
        params: &PyramidParams,
        input: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// Per-column Gauss-Newton sums of a bone's rigid registration (abi::RIGID_SUMS per
    /// column of the source, layout of shaders/rigid_gn.wgsl) at the motion in `params`.
    fn rigid_sums(
        &self,
        params: &RigidParams,
        images: &BoneImages<Self::Buffer<f32>>,
    ) -> Result<Self::Buffer<f32>>;

    /// Per-column (Σ r², count) of every candidate motion (12 floats each, abi::pack_candidates;
    /// layout of shaders/rigid_score.wgsl).
    fn rigid_scores(
        &self,
        params: &ScoreParams,
        images: &BoneImages<Self::Buffer<f32>>,
        candidates: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// Skinning weights (bones per voxel) from distance maps (bones per voxel, mm) on `grid`.
    fn skin_weights(
        &self,
        distances: &[f32],
        grid: &Grid,
        bones: usize,
        power: u32,
    ) -> Result<Vec<f32>>;

    /// The inverted blend on `target`: 4 floats per voxel (u in mm, inversion residual in mm)
    /// for bones moving and blended as `blend` says, weights (bones per voxel) on `weight_grid`, and
    /// `bone_of_voxel` (1 + bone index, 0 for soft tissue) on the source label grid `labels`.
    fn skin_blend(
        &self,
        weights: &[f32],
        weight_grid: &Grid,
        bone_of_voxel: &[f32],
        labels: &Grid,
        target: &Grid,
        blend: &BoneBlend,
    ) -> Result<Vec<f32>>;

    /// `moving` seen through the warp `lattice` (3 floats per node) at every voxel of the grid
    /// in `params`: W(x) = I0(x + R(x)), 0 outside.
    fn warp_image(
        &self,
        params: &RbfGradParams,
        lattice: &Self::Buffer<f32>,
        moving: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// W · T and W · W per voxel: what the intensity gain smooths (gain.rs).
    fn gain_terms(
        &self,
        params: &GainParams,
        warped: &Self::Buffer<f32>,
        target: &Self::Buffer<f32>,
    ) -> Result<(Self::Buffer<f32>, Self::Buffer<f32>)>;

    /// The gain on the smoothed grid: product / energy, clamped, 1 where energy is at or below
    /// the floor.
    fn gain_ratio(
        &self,
        params: &GainParams,
        product: &Self::Buffer<f32>,
        energy: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// `moving` times the gain interpolated from the smoothed grid.
    fn gain_apply(
        &self,
        params: &GainParams,
        gain: &Self::Buffer<f32>,
        moving: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// The warp R at every voxel of `grid`, interpolated from `lattice` (3 floats per node of a
    /// lattice of `lattice_dims` nodes every `step` voxels) as the non-rigid cost does.
    fn warp_field(
        &self,
        lattice: &[f32],
        lattice_dims: [usize; 3],
        step: usize,
        grid: &Grid,
    ) -> Result<Field>;

    /// The total field u = R + u0 ∘ (id + R) of a warp R and an initial field u0 on one grid.
    fn compose(&self, warp: &Field, initial: &Field) -> Result<Field>;

    /// The warp R at every lattice node (3 f32 per node), the cubic RBF `spline` (f64, layout
    /// of abi::spline_buffer) evaluated in f64 at nodes placed by `geometry`
    /// (abi::lattice_geometry).
    fn rbf_lattice(
        &self,
        params: &RbfLatticeParams,
        geometry: &Self::Buffer<f64>,
        spline: &Self::Buffer<f64>,
    ) -> Result<Self::Buffer<f32>>;

    /// The image part of a non-rigid cost evaluation through the warp `lattice`: the masked
    /// gradient (3 floats per voxel) and Σ c (W − T)² per row of x (ny · nz floats).
    fn warp_cost(
        &self,
        params: &RbfGradParams,
        lattice: &Self::Buffer<f32>,
        images: &CostImages<Self::Buffer<f32>>,
    ) -> Result<(Self::Buffer<f32>, Self::Buffer<f32>)>;

    /// The adjoint of the lattice interpolation: 3 floats per lattice node, Σ_x w_n(x) v(x),
    /// from 3 floats per voxel.
    fn lattice_splat(
        &self,
        params: &SplatParams,
        values: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f32>>;

    /// The lattice energy's terms (1 float per node) and the whole cost's gradient at each
    /// node (3 floats): `splat` scaled, plus the energy's gradient.
    fn lattice_energy(
        &self,
        params: &EnergyParams,
        lattice: &Self::Buffer<f32>,
        splat: &Self::Buffer<f32>,
    ) -> Result<(Self::Buffer<f32>, Self::Buffer<f32>)>;

    /// The gradient with respect to the RBF's coefficients from the gradient at the nodes, as
    /// partial sums per chunk of nodes (f64: per chunk, 3 per control point, then 3 per affine
    /// row; [`Backend::sum_partials`] adds them).
    fn rbf_adjoint(
        &self,
        params: &RbfLatticeParams,
        geometry: &Self::Buffer<f64>,
        spline: &Self::Buffer<f64>,
        node_gradient: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f64>>;

    /// Per-chunk partial results of `values` values each, added in chunk order (in groups,
    /// abi::PartialsParams::passes), in f64.
    fn sum_partials<T: Element>(
        &self,
        partials: &Self::Buffer<T>,
        values: usize,
    ) -> Result<Self::Buffer<f64>>;

    /// Sums of (v − shift)^power over chunks of abi::SUM_CHUNK values, in f64 (`params`).
    fn sum_chunks(
        &self,
        params: &SumParams,
        values: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f64>>;
}

/// Σ (v − shift)^power over all of `values` (`params`), reduced where the backend computes; the
/// chunks' sums come back and are added here.
pub fn total<B: Backend>(backend: &B, params: &SumParams, values: &B::Buffer<f32>) -> Result<f64> {
    let sums = backend.sum_chunks(params, values)?;
    Ok(backend.download_one(&sums)?.iter().sum())
}

/// Checks two images (volumes or fields) combined voxel by voxel share a grid.
pub fn check_pair<T, U>(a: &Image<T>, b: &Image<U>) -> Result<()> {
    check_grids(&a.grid, &b.grid)
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

/// `volume` sampled on `grid` without any displacement (trilinear, 0 outside): the unregistered
/// source seen on the target's grid.
pub fn resample_onto<B: Backend>(backend: &B, volume: &Volume, grid: &Grid) -> Result<Volume> {
    let zero = crate::volume::Image::filled(grid.clone(), [0.0f32; 3]);
    backend.resample(volume, &zero, 0.0, Interpolation::Linear)
}
