//! The adaptive stage's kernels: the RBF warp on its lattice and through it, the cost's image
//! terms and their adjoints, the lattice energy, the per-cell SSD and the intensity gain
//! (shaders/nonrigid/, abi::nonrigid, cpu::nonrigid, gpu::nonrigid).

use super::Core;
use crate::abi::{
    EnergyParams, GainParams, RbfGradParams, RbfLatticeParams, SplatParams, SsdParams,
};
use crate::error::Result;

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

/// Kernels of the non-rigid (adaptive) stage.
pub trait NonRigid: Core {
    /// Per-column partial sums of c (a − b)² per cell (layout of shaders/nonrigid/ssd_cells.wgsl, folded
    /// by metric::fold_ssd_partials): a = `images.moving`, b = `images.fixed`, c = 1 where
    /// `images.covered` says the moving image holds data.
    fn ssd_cells(
        &self,
        params: &SsdParams,
        images: &CostImages<Self::Buffer<f32>>,
    ) -> Result<Self::Buffer<f32>>;

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
    /// row; [`super::reduce::Reduce::sum_partials`] adds them).
    fn rbf_adjoint(
        &self,
        params: &RbfLatticeParams,
        geometry: &Self::Buffer<f64>,
        spline: &Self::Buffer<f64>,
        node_gradient: &Self::Buffer<f32>,
    ) -> Result<Self::Buffer<f64>>;
}
