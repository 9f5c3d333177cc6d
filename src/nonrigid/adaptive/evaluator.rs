//! The adaptive stage's cost on the device: the warp of the control points evaluated on a
//! coarse lattice and interpolated per voxel, the image term and the membrane and bending
//! energies, and the gradient back through the adjoints; one pass of kernels per evaluation.

use crate::abi::{
    lattice_geometry, spline_buffer, EnergyParams, RbfGradParams, RbfLatticeParams, SplatParams,
    SumParams,
};
use crate::backend::{Backend, CostImages, DeviceImage};
use crate::error::Result;
use crate::images::similarity::LnccCost;
use crate::nonrigid::rbf::RbfCoefficients;
use crate::nonrigid::regularise::energy_params;
use crate::volume::Grid;
use nalgebra::Vector3;

/// A lattice of nodes every `step` voxels (per axis) over a grid, lattice where the backend
/// computes: the warp is evaluated at its nodes and interpolated at the grid's voxels.
pub(super) struct Lattice<B: Backend> {
    pub(super) dims: [usize; 3],
    pub(super) step: [usize; 3],
    pub(super) spacing_mm: [f64; 3],
    pub(super) geometry: B::Buffer<f64>,
    /// Parameters of the kernels that interpolate it at the grid's voxels.
    pub(super) voxel_params: RbfGradParams,
}

impl<B: Backend> Lattice<B> {
    /// A lattice over every `stride`-th voxel of `moving` (the moving image's grid), nodes
    /// every `step` of those voxels.
    pub(super) fn new(backend: &B, moving: &Grid, stride: usize, step: [usize; 3]) -> Result<Self> {
        let grid = moving.every(stride);
        let dims: [usize; 3] = std::array::from_fn(|a| (grid.dims[a] - 1).div_ceil(step[a]) + 1);
        let spacing = grid.spacing();
        Ok(Lattice {
            dims,
            step,
            spacing_mm: std::array::from_fn(|a| spacing[a] * step[a] as f64),
            geometry: backend.upload("lattice geometry", lattice_geometry(&grid))?,
            voxel_params: RbfGradParams::sampling(moving, stride, dims, step),
        })
    }

    /// The RBF `coef` (centres `centres`) at the nodes (rbf_lattice), with the uploaded
    /// spline and the kernel's shape, for the adjoint to reuse.
    pub(super) fn warp(
        &self,
        backend: &B,
        coef: &RbfCoefficients,
        centres: &[Vector3<f64>],
    ) -> Result<NodeWarp<B>> {
        let positions: Vec<[f64; 3]> = centres.iter().map(|c| [c.x, c.y, c.z]).collect();
        let spline = backend.upload(
            "RBF coefficients",
            spline_buffer(&coef.affine, &positions, &coef.lambda),
        )?;
        let shape = RbfLatticeParams::new(self.dims, self.step, centres.len());
        let values = backend.rbf_lattice(&shape, &self.geometry, &spline)?;
        Ok(NodeWarp {
            spline,
            shape,
            values,
        })
    }
}

/// A warp evaluated at a lattice's nodes.
pub(super) struct NodeWarp<B: Backend> {
    pub(super) spline: B::Buffer<f64>,
    pub(super) shape: RbfLatticeParams,
    /// 3 floats (R, mm) per node.
    pub(super) values: B::Buffer<f32>,
}

/// One pyramid level's images where the backend computes.
pub(super) struct Level<B: Backend> {
    /// The target, on every `stride`-th voxel of the moving image's grid.
    pub(super) fixed: DeviceImage<B>,
    pub(super) moving: DeviceImage<B>,
    /// 1 but at a finest level measured on fewer voxels (AdaptiveOptions::finest_stride).
    pub(super) stride: usize,
    pub(super) covered: DeviceImage<B>,
    /// [`Moving::mask_share`].
    pub(super) mask_share: f64,
}

impl<B: Backend> Level<B> {
    pub(super) fn images<'a>(
        &'a self,
        moving: &'a B::Buffer<f32>,
    ) -> CostImages<'a, B::Buffer<f32>> {
        CostImages {
            moving,
            fixed: &self.fixed.data,
            covered: &self.covered.data,
        }
    }
}

/// The optimiser's view of one pyramid level: each evaluation uploads the RBF's coefficients,
/// runs the cost's kernels, and reads back only the gradient with respect to the coefficients
/// and a few partial sums.
pub(super) struct Evaluator<'a, B: Backend> {
    pub(super) backend: &'a B,
    pub(super) lattice: &'a Lattice<B>,
    pub(super) images: CostImages<'a, B::Buffer<f32>>,
    /// None for SSD.
    pub(super) lncc: Option<LnccCost>,
    pub(super) splat: SplatParams,
    pub(super) energy: EnergyParams,
    pub(super) voxels: f64,
}

impl<'a, B: Backend> Evaluator<'a, B> {
    /// `weights` are the membrane's and the bending energy's at this level.
    pub(super) fn new(
        backend: &'a B,
        lattice: &'a Lattice<B>,
        images: CostImages<'a, B::Buffer<f32>>,
        lncc: Option<LnccCost>,
        grid: &Grid,
        weights: [f64; 2],
    ) -> Self {
        let voxels = grid.len() as f64;
        Evaluator {
            backend,
            lattice,
            images,
            lncc,
            splat: SplatParams::new(lattice.dims, lattice.step, grid.dims),
            energy: energy_params(
                lattice.dims,
                lattice.spacing_mm,
                weights[0],
                weights[1],
                (1.0 / voxels) as f32,
            ),
            voxels,
        }
    }

    /// The cost of the warp `coef` (centres `centres`): the mean masked squared residual plus
    /// the lattice energies; and its gradient with respect to the coefficients, per control
    /// point and per affine row.
    pub(super) fn evaluate(
        &self,
        coef: &RbfCoefficients,
        centres: &[Vector3<f64>],
    ) -> Result<Evaluated> {
        let b = self.backend;
        let warp = self.lattice.warp(b, coef, centres)?;
        let voxel_params = &self.lattice.voxel_params;
        let (per_voxel, rows) = match &self.lncc {
            None => b.warp_cost(voxel_params, &warp.values, &self.images)?,
            Some(lncc) => lncc.evaluate(b, voxel_params, &warp.values, &self.images)?,
        };
        let splat = b.lattice_splat(&self.splat, &per_voxel)?;
        let (node_gradient, energy) = b.lattice_energy(&self.energy, &warp.values, &splat)?;
        let partials = b.rbf_adjoint(
            &warp.shape,
            &self.lattice.geometry,
            &warp.spline,
            &node_gradient,
        )?;
        let adjoint = b.sum_partials(&partials, 3 * warp.shape.rows())?;
        let sum = |v: &B::Buffer<f32>, n| b.sum_chunks(&SumParams::new(n), v);
        let rows = sum(&rows, self.lattice.voxel_params.rows())?;
        let energy = sum(&energy, self.energy.nodes())?;
        let [adjoint, rows, energy]: [Vec<f64>; 3] = b
            .download(&[&adjoint, &rows, &energy])?
            .try_into()
            .expect("three buffers asked for");
        let cost = rows.iter().sum::<f64>() / self.voxels + energy.iter().sum::<f64>();
        let rows: Vec<Vector3<f64>> = adjoint
            .chunks_exact(3)
            .map(|v| Vector3::new(v[0], v[1], v[2]))
            .collect();
        Ok(Evaluated {
            cost,
            affine: std::array::from_fn(|k| rows[centres.len() + k]),
            points: rows[..centres.len()].to_vec(),
        })
    }
}

/// One evaluation's cost and its gradient with respect to the RBF's coefficients.
pub(super) struct Evaluated {
    pub(super) cost: f64,
    /// Per control point (its λ).
    pub(super) points: Vec<Vector3<f64>>,
    /// Per affine row (1, x, y, z).
    pub(super) affine: [Vector3<f64>; 4],
}
