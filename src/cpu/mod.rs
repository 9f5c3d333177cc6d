//! The CPU backend: each kernel's twin, written to read like its shader, parallel over slices
//! with rayon. It is a full backend (machines without a GPU use it) and the reference the GPU
//! path is tested against.
//!
//! The hottest loops (a row, slice or block of a kernel) are `#[multiversion]` functions:
//! compiled also for AVX2 and chosen at run time, so a machine that has it runs them in wider
//! lanes, and one that has not still runs them. Both versions perform the same IEEE operations
//! in the same order (Rust never fuses a multiply and an add on its own), so they give the same
//! bits; a function they call must be inlined into them (`#[inline(always)]` where the
//! compiler declines) to be compiled for AVX2 too. So must a closure: the compiler has left
//! those of `std::array::from_fn`, an array's `map` and `extend` over a `map` behind calls in
//! hot loops, where `sample::array_from` and plain loops are inlined.

pub mod common;
pub mod correlation;
pub mod dense;
mod fade;
pub mod field;
pub mod fold;
pub mod gain;
pub mod labels;
pub mod lattice_energy;
pub mod lattice_splat;
pub mod lattice_warp;
pub mod rbf_adjoint;
pub mod rbf_lattice;
pub mod reduce;
pub mod regions;
pub mod rigid;
pub mod sampling;
pub mod skinning;
pub mod ssd_cells;
pub mod warp_cost;
pub mod warp_image;
mod window;

use crate::abi::{
    EnergyParams, GainParams, RbfGradParams, RbfLatticeParams, SplatParams, SsdParams,
};
use crate::backend::{Backend, Core, CostImages, Element, Traffic};
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

/// A new buffer of `len` values, filled by `twin`.
fn filled<T: Element>(len: usize, twin: impl FnOnce(&mut [T])) -> Result<Arc<Vec<T>>> {
    let mut out = zeroed(len);
    twin(&mut out);
    Ok(Arc::new(out))
}

/// A kernel's two output buffers.
type BufferPair<T> = (Arc<Vec<T>>, Arc<Vec<T>>);

/// Two new buffers of `lens[0]` and `lens[1]` values, filled together by `twin`.
fn filled_pair<T: Element>(
    lens: [usize; 2],
    twin: impl FnOnce(&mut [T], &mut [T]),
) -> Result<BufferPair<T>> {
    let [mut first, mut second] = lens.map(zeroed);
    twin(&mut first, &mut second);
    Ok((Arc::new(first), Arc::new(second)))
}

/// `len` zeros, written by every thread. Zeroed on one thread (`vec!`), the kernels' output
/// buffers were 5% of a registration's CPU time on the half phantom, the memset and the first
/// touch of fresh pages, with the other cores idle.
fn zeroed<T: Element>(len: usize) -> Vec<T> {
    let mut out = Vec::with_capacity(len);
    rayon::iter::ParallelExtend::par_extend(&mut out, rayon::iter::repeat_n(T::zeroed(), len));
    out
}

/// Runs every kernel on the host's cores.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuBackend;

impl Core for CpuBackend {
    type Buffer<T: Element> = Arc<Vec<T>>;

    fn upload<T: Element>(&self, _what: &str, data: Vec<T>) -> Result<Arc<Vec<T>>> {
        Ok(Arc::new(data))
    }

    fn zeros(&self, _what: &str, len: usize) -> Result<Arc<Vec<f32>>> {
        Ok(Arc::new(zeroed(len)))
    }

    fn download<T: Element>(&self, buffers: &[&Arc<Vec<T>>]) -> Result<Vec<Vec<T>>> {
        Ok(buffers.iter().map(|b| b.to_vec()).collect())
    }

    fn describe(&self) -> String {
        format!("cpu: {} threads", rayon::current_num_threads())
    }

    fn traffic(&self) -> Traffic {
        Traffic::default()
    }
}

impl Backend for CpuBackend {
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
            gain::gain_terms(warped, target, product, energy);
        })
    }

    fn gain_ratio(
        &self,
        params: &GainParams,
        product: &Arc<Vec<f32>>,
        energy: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            gain::gain_ratio(params, product, energy, out)
        })
    }

    fn gain_apply(
        &self,
        params: &GainParams,
        gain: &Arc<Vec<f32>>,
        moving: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.voxels(), |out| {
            gain::gain_apply(params, gain, moving, out)
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
