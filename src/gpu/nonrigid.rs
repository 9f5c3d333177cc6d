//! Host side of the non-rigid family (shaders/nonrigid/): the adaptive stage's kernels, their
//! bindings, their compiled pipelines and the family's trait. Each records one dispatch on
//! device buffers and returns its outputs as device buffers (see resident.rs). Whole grids are
//! bound at once: a volume whose per-voxel gradient (12 bytes a voxel) exceeds the device's
//! binding limit gets a `DeviceLimit` error naming it.

use super::context::GpuContext;
use super::kernel::{cover, groups, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::{
    EnergyParams, GainParams, RbfGradParams, RbfLatticeParams, SplatParams, SsdParams,
};
use crate::backend::nonrigid::{CostImages, NonRigid};
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("ssd_cells", &[Uniform, Read, Read, Read, ReadWrite]),
    ("warp_image", &[Uniform, Read, Read, ReadWrite]),
    ("gain_terms", &[Uniform, Read, Read, ReadWrite, ReadWrite]),
    ("gain_ratio", &[Uniform, Read, Read, ReadWrite]),
    ("gain_apply", &[Uniform, Read, Read, ReadWrite]),
    ("rbf_lattice", &[Uniform, Read, Read, ReadWrite]),
    (
        "warp_cost",
        &[Uniform, Read, Read, Read, Read, ReadWrite, ReadWrite],
    ),
    ("lattice_splat", &[Uniform, Read, ReadWrite]),
    (
        "lattice_energy",
        &[Uniform, Read, Read, ReadWrite, ReadWrite],
    ),
    ("rbf_adjoint", &[Uniform, Read, Read, Read, ReadWrite]),
];

/// The family's compiled kernels.
pub struct NonRigidKernels {
    ssd_cells: Kernel,
    warp_image: Kernel,
    gain_terms: Kernel,
    gain_ratio: Kernel,
    gain_apply: Kernel,
    rbf_lattice: Kernel,
    warp_cost: Kernel,
    lattice_splat: Kernel,
    lattice_energy: Kernel,
    rbf_adjoint: Kernel,
}

impl NonRigidKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(NonRigidKernels {
            ssd_cells: compile(ctx, "ssd_cells")?,
            warp_image: compile(ctx, "warp_image")?,
            gain_terms: compile(ctx, "gain_terms")?,
            gain_ratio: compile(ctx, "gain_ratio")?,
            gain_apply: compile(ctx, "gain_apply")?,
            rbf_lattice: compile(ctx, "rbf_lattice")?,
            warp_cost: compile(ctx, "warp_cost")?,
            lattice_splat: compile(ctx, "lattice_splat")?,
            lattice_energy: compile(ctx, "lattice_energy")?,
            rbf_adjoint: compile(ctx, "rbf_adjoint")?,
        })
    }
}

impl NonRigid for GpuBackend {
    /// shaders/nonrigid/rbf_lattice.wgsl
    fn rbf_lattice(
        &self,
        params: &RbfLatticeParams,
        geometry: &GpuBuffer<f64>,
        spline: &GpuBuffer<f64>,
    ) -> Result<GpuBuffer<f32>> {
        let values = self.output_buffer("warp at the lattice nodes", 3 * params.nodes())?;
        self.record(
            &self.kernels.nonrigid.rbf_lattice,
            params,
            &[geometry.raw(), spline.raw(), values.raw()],
            cover(params.lattice, 4),
        )?;
        Ok(values)
    }

    /// shaders/nonrigid/warp_cost.wgsl
    fn warp_cost(
        &self,
        params: &RbfGradParams,
        lattice: &GpuBuffer<f32>,
        images: &CostImages<GpuBuffer<f32>>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let [nx, ny, nz, _] = params.dims.map(|n| n as usize);
        let gradient = self.output_buffer("per-voxel cost gradient", 3 * nx * ny * nz)?;
        let rows = self.output_buffer("per-row cost", ny * nz)?;
        self.record(
            &self.kernels.nonrigid.warp_cost,
            params,
            &[
                lattice.raw(),
                images.moving.raw(),
                images.fixed.raw(),
                images.covered.raw(),
                gradient.raw(),
                rows.raw(),
            ],
            [groups(ny, 8), groups(nz, 8), 1],
        )?;
        Ok((gradient, rows))
    }

    /// shaders/nonrigid/lattice_splat.wgsl
    fn lattice_splat(
        &self,
        params: &SplatParams,
        values: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let nodes = params.nodes();
        let out = self.output_buffer("gradient at the lattice nodes", 3 * nodes)?;
        self.record(
            &self.kernels.nonrigid.lattice_splat,
            params,
            &[values.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// shaders/nonrigid/lattice_energy.wgsl
    fn lattice_energy(
        &self,
        params: &EnergyParams,
        lattice: &GpuBuffer<f32>,
        splat: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let gradient = self.output_buffer("cost gradient at the nodes", 3 * params.nodes())?;
        let energy = self.output_buffer("lattice energy terms", params.nodes())?;
        self.record(
            &self.kernels.nonrigid.lattice_energy,
            params,
            &[lattice.raw(), splat.raw(), gradient.raw(), energy.raw()],
            cover(params.dims, 4),
        )?;
        Ok((gradient, energy))
    }

    /// shaders/nonrigid/rbf_adjoint.wgsl
    fn rbf_adjoint(
        &self,
        params: &RbfLatticeParams,
        geometry: &GpuBuffer<f64>,
        spline: &GpuBuffer<f64>,
        node_gradient: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f64>> {
        let rows = params.rows();
        let partials = self.output_buffer(
            "partial gradients of the RBF coefficients",
            3 * rows * params.chunks(),
        )?;
        self.record(
            &self.kernels.nonrigid.rbf_adjoint,
            params,
            &[
                geometry.raw(),
                spline.raw(),
                node_gradient.raw(),
                partials.raw(),
            ],
            [groups(rows, 64), params.chunks() as u32, 1],
        )?;
        Ok(partials)
    }

    /// shaders/nonrigid/warp_image.wgsl
    fn warp_image(
        &self,
        params: &RbfGradParams,
        lattice: &GpuBuffer<f32>,
        moving: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let warped = self.output_buffer("warped image", params.voxels())?;
        self.record(
            &self.kernels.nonrigid.warp_image,
            params,
            &[lattice.raw(), moving.raw(), warped.raw()],
            cover(params.dims, 4),
        )?;
        Ok(warped)
    }

    /// shaders/nonrigid/ssd_cells.wgsl
    fn ssd_cells(
        &self,
        params: &SsdParams,
        images: &CostImages<GpuBuffer<f32>>,
    ) -> Result<GpuBuffer<f32>> {
        let partial = self.output_buffer("cell SSD partial sums", params.partials())?;
        self.record(
            &self.kernels.nonrigid.ssd_cells,
            params,
            &[
                images.moving.raw(),
                images.fixed.raw(),
                images.covered.raw(),
                partial.raw(),
            ],
            [groups(params.dims[0] as usize, 64), params.dims[2], 1],
        )?;
        Ok(partial)
    }

    /// shaders/nonrigid/gain_terms.wgsl
    fn gain_terms(
        &self,
        params: &GainParams,
        warped: &GpuBuffer<f32>,
        target: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let product = self.output_buffer("gain product", params.voxels())?;
        let energy = self.output_buffer("gain energy", params.voxels())?;
        self.record(
            &self.kernels.nonrigid.gain_terms,
            params,
            &[warped.raw(), target.raw(), product.raw(), energy.raw()],
            cover(params.dims, 4),
        )?;
        Ok((product, energy))
    }

    /// shaders/nonrigid/gain_ratio.wgsl
    fn gain_ratio(
        &self,
        params: &GainParams,
        product: &GpuBuffer<f32>,
        energy: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let gain = self.output_buffer("gain", params.voxels())?;
        self.record(
            &self.kernels.nonrigid.gain_ratio,
            params,
            &[product.raw(), energy.raw(), gain.raw()],
            cover(params.dims, 4),
        )?;
        Ok(gain)
    }

    /// shaders/nonrigid/gain_apply.wgsl
    fn gain_apply(
        &self,
        params: &GainParams,
        gain: &GpuBuffer<f32>,
        moving: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let gained = self.output_buffer("moving image with its gain", params.voxels())?;
        self.record(
            &self.kernels.nonrigid.gain_apply,
            params,
            &[gain.raw(), moving.raw(), gained.raw()],
            cover(params.dims, 4),
        )?;
        Ok(gained)
    }
}
