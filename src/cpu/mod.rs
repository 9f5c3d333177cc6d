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
pub mod labels;
pub mod lattice_warp;
pub mod nonrigid;
pub mod reduce;
pub mod regions;
pub mod rigid;
pub mod row_cells;
pub mod sampling;
pub mod skinning;
mod window;

use crate::backend::{Backend, Core, Element, Traffic};
use crate::error::Result;
use std::sync::Arc;

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

impl Backend for CpuBackend {}

impl Core for CpuBackend {
    type Buffer<T: Element> = Arc<Vec<T>>;

    fn upload<T: Element>(&self, _what: &str, data: Vec<T>) -> Result<Arc<Vec<T>>> {
        Ok(Arc::new(data))
    }

    fn zeros<T: Element>(&self, _what: &str, len: usize) -> Result<Arc<Vec<T>>> {
        Ok(Arc::new(zeroed(len)))
    }

    fn duplicate<T: Element>(&self, _what: &str, buffer: &Arc<Vec<T>>) -> Result<Arc<Vec<T>>> {
        Ok(Arc::new(buffer.to_vec()))
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
