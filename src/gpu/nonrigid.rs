//! Host side of the non-rigid stage's resident kernels: each records one dispatch on device
//! buffers and returns its outputs as device buffers (see resident.rs). Whole grids are bound
//! at once: a volume whose per-voxel gradient (12 bytes a voxel) exceeds the device's binding
//! limit gets a `DeviceLimit` error naming it.

use super::kernel::{cover, groups, Binding};
use super::resident::GpuBuffer;
use super::GpuBackend;
use crate::abi::{
    EnergyParams, GainParams, RbfGradParams, RbfLatticeParams, SplatParams, SsdParams,
};
use crate::backend::CostImages;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// rbf_lattice bindings in the order the shader declares them.
pub const LATTICE_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];
/// warp_cost bindings.
pub const COST_BINDINGS: &[Binding] = &[Uniform, Read, Read, Read, Read, ReadWrite, ReadWrite];
/// lattice_splat bindings.
pub const SPLAT_BINDINGS: &[Binding] = &[Uniform, Read, ReadWrite];
/// lattice_energy bindings.
pub const ENERGY_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite, ReadWrite];
/// rbf_adjoint bindings.
pub const ADJOINT_BINDINGS: &[Binding] = &[Uniform, Read, Read, Read, ReadWrite];
/// warp_image bindings.
pub const WARP_IMAGE_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];
/// ssd_cells bindings.
pub const SSD_BINDINGS: &[Binding] = &[Uniform, Read, Read, Read, ReadWrite];
/// gain_terms bindings.
pub const GAIN_TERMS_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite, ReadWrite];
/// gain_ratio and gain_apply bindings.
pub const GAIN_BINDINGS: &[Binding] = &[Uniform, Read, Read, ReadWrite];

impl GpuBackend {
    /// shaders/rbf_lattice.wgsl
    pub fn record_rbf_lattice(
        &self,
        params: &RbfLatticeParams,
        geometry: &GpuBuffer<f64>,
        spline: &GpuBuffer<f64>,
    ) -> Result<GpuBuffer<f32>> {
        let values = self.output_buffer("warp at the lattice nodes", 3 * params.nodes())?;

        self.record(
            &self.kernels.rbf_lattice,
            params,
            &[geometry.raw(), spline.raw(), values.raw()],
            cover(params.lattice, 4),
        )?;
        Ok(values)
    }

    /// shaders/warp_cost.wgsl
    pub fn record_warp_cost(
        &self,
        params: &RbfGradParams,
        lattice: &GpuBuffer<f32>,
        images: &CostImages<GpuBuffer<f32>>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let [nx, ny, nz, _] = params.dims.map(|n| n as usize);
        let gradient = self.output_buffer("per-voxel cost gradient", 3 * nx * ny * nz)?;
        let rows = self.output_buffer("per-row cost", ny * nz)?;
        self.record(
            &self.kernels.warp_cost,
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

    /// shaders/lattice_splat.wgsl
    pub fn record_lattice_splat(
        &self,
        params: &SplatParams,
        values: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let nodes = params.nodes();
        let out = self.output_buffer("gradient at the lattice nodes", 3 * nodes)?;
        self.record(
            &self.kernels.lattice_splat,
            params,
            &[values.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// shaders/lattice_energy.wgsl
    pub fn record_lattice_energy(
        &self,
        params: &EnergyParams,
        lattice: &GpuBuffer<f32>,
        splat: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let gradient = self.output_buffer("cost gradient at the nodes", 3 * params.nodes())?;
        let energy = self.output_buffer("lattice energy terms", params.nodes())?;
        self.record(
            &self.kernels.lattice_energy,
            params,
            &[lattice.raw(), splat.raw(), gradient.raw(), energy.raw()],
            cover(params.dims, 4),
        )?;
        Ok((gradient, energy))
    }

    /// shaders/rbf_adjoint.wgsl
    pub fn record_rbf_adjoint(
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
            &self.kernels.rbf_adjoint,
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

    /// shaders/warp_image.wgsl
    pub fn record_warp_image(
        &self,
        params: &RbfGradParams,
        lattice: &GpuBuffer<f32>,
        moving: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let warped = self.output_buffer("warped image", params.voxels())?;
        self.record(
            &self.kernels.warp_image,
            params,
            &[lattice.raw(), moving.raw(), warped.raw()],
            cover(params.dims, 4),
        )?;
        Ok(warped)
    }

    /// shaders/ssd_cells.wgsl
    pub fn record_ssd_cells(
        &self,
        params: &SsdParams,
        images: &CostImages<GpuBuffer<f32>>,
    ) -> Result<GpuBuffer<f32>> {
        let partial = self.output_buffer("cell SSD partial sums", params.partials())?;
        self.record(
            &self.kernels.ssd_cells,
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

    /// shaders/gain_terms.wgsl
    pub fn record_gain_terms(
        &self,
        params: &GainParams,
        warped: &GpuBuffer<f32>,
        target: &GpuBuffer<f32>,
    ) -> Result<(GpuBuffer<f32>, GpuBuffer<f32>)> {
        let product = self.output_buffer("gain product", params.voxels())?;
        let energy = self.output_buffer("gain energy", params.voxels())?;
        self.record(
            &self.kernels.gain_terms,
            params,
            &[warped.raw(), target.raw(), product.raw(), energy.raw()],
            cover(params.dims, 4),
        )?;
        Ok((product, energy))
    }

    /// shaders/gain_ratio.wgsl
    pub fn record_gain_ratio(
        &self,
        params: &GainParams,
        product: &GpuBuffer<f32>,
        energy: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let gain = self.output_buffer("gain", params.voxels())?;
        self.record(
            &self.kernels.gain_ratio,
            params,
            &[product.raw(), energy.raw(), gain.raw()],
            cover(params.dims, 4),
        )?;
        Ok(gain)
    }

    /// shaders/gain_apply.wgsl
    pub fn record_gain_apply(
        &self,
        params: &GainParams,
        gain: &GpuBuffer<f32>,
        moving: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let gained = self.output_buffer("moving image with its gain", params.voxels())?;
        self.record(
            &self.kernels.gain_apply,
            params,
            &[gain.raw(), moving.raw(), gained.raw()],
            cover(params.dims, 4),
        )?;
        Ok(gained)
    }
}
