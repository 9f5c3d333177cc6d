//! CPU twins of the non-rigid family's kernels (shaders/nonrigid/).

mod gain_apply;
mod gain_ratio;
mod gain_terms;
mod lattice_energy;
mod lattice_splat;
mod rbf_adjoint;
mod rbf_lattice;
mod rbf_nodes;
mod ssd_cells;
mod warp_cost;
mod warp_image;

use super::{filled, filled_pair, CpuBackend};
use crate::abi::{
    EnergyParams, GainParams, RbfGradParams, RbfLatticeParams, SplatParams, SsdParams,
};
use crate::backend::nonrigid::{CostImages, NonRigid};
use crate::error::Result;
use std::sync::Arc;

/// The cost images as slices, for the twins.
fn as_slices<'a>(images: &CostImages<'a, Arc<Vec<f32>>>) -> CostImages<'a, [f32]> {
    CostImages {
        moving: images.moving.as_slice(),
        fixed: images.fixed.as_slice(),
        covered: images.covered.as_slice(),
    }
}

impl NonRigid for CpuBackend {
    fn ssd_cells(
        &self,
        params: &SsdParams,
        images: &CostImages<Arc<Vec<f32>>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.partials(), |out| {
            ssd_cells::ssd_cells(params, &as_slices(images), out)
        })
    }

    fn warp_image(
        &self,
        params: &RbfGradParams,
        lattice: &Arc<Vec<f32>>,
        moving: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            warp_image::warp_image(params, lattice, moving, out)
        })
    }

    fn gain_terms(
        &self,
        params: &GainParams,
        warped: &Arc<Vec<f32>>,
        target: &Arc<Vec<f32>>,
    ) -> Result<(Arc<Vec<f32>>, Arc<Vec<f32>>)> {
        filled_pair([params.voxels(), params.voxels()], |product, energy| {
            gain_terms::gain_terms(warped, target, product, energy);
        })
    }

    fn gain_ratio(
        &self,
        params: &GainParams,
        product: &Arc<Vec<f32>>,
        energy: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            gain_ratio::gain_ratio(params, product, energy, out)
        })
    }

    fn gain_apply(
        &self,
        params: &GainParams,
        gain: &Arc<Vec<f32>>,
        moving: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            gain_apply::gain_apply(params, gain, moving, out)
        })
    }

    fn rbf_lattice(
        &self,
        params: &RbfLatticeParams,
        geometry: &Arc<Vec<f64>>,
        spline: &Arc<Vec<f64>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(3 * params.nodes(), |out| {
            rbf_lattice::rbf_lattice(params, geometry, spline, out)
        })
    }

    fn warp_cost(
        &self,
        params: &RbfGradParams,
        lattice: &Arc<Vec<f32>>,
        images: &CostImages<Arc<Vec<f32>>>,
    ) -> Result<(Arc<Vec<f32>>, Arc<Vec<f32>>)> {
        filled_pair([3 * params.voxels(), params.rows()], |gradient, rows| {
            warp_cost::warp_cost(params, lattice, &as_slices(images), gradient, rows);
        })
    }

    fn lattice_splat(&self, params: &SplatParams, values: &Arc<Vec<f32>>) -> Result<Arc<Vec<f32>>> {
        let nodes = params.nodes();
        filled(3 * nodes, |out| {
            lattice_splat::lattice_splat(params, values, out)
        })
    }

    fn lattice_energy(
        &self,
        params: &EnergyParams,
        lattice: &Arc<Vec<f32>>,
        splat: &Arc<Vec<f32>>,
    ) -> Result<(Arc<Vec<f32>>, Arc<Vec<f32>>)> {
        filled_pair([3 * params.nodes(), params.nodes()], |gradient, energy| {
            lattice_energy::lattice_energy(params, lattice, splat, gradient, energy);
        })
    }

    fn rbf_adjoint(
        &self,
        params: &RbfLatticeParams,
        geometry: &Arc<Vec<f64>>,
        spline: &Arc<Vec<f64>>,
        node_gradient: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f64>>> {
        filled(3 * params.rows() * params.chunks(), |out| {
            rbf_adjoint::rbf_adjoint(params, geometry, spline, node_gradient, out)
        })
    }
}
