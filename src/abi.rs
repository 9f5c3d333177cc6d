//! Parameter structs shared with the WGSL kernels, byte for byte.
//!
//! Each struct is `#[repr(C)]` Pod with u32/f32/[f32; 4] fields and explicit padding (never a
//! vec3, whose 16-byte alignment differs between Rust and WGSL). Each is mirrored by a struct of
//! the same name in its shader; `tests/shaders.rs` checks the sizes through naga reflection.
//! The constructors do the f64 host-side geometry once, so both backends receive identical f32s.

use crate::error::{Error, Result};
use crate::volume::{Affine, Grid};
use bytemuck::{Pod, Zeroable};

mod correlation;
pub mod dense;
mod field;
mod fold;
mod labels;
mod nonrigid;
mod reduce;
mod regions;
mod rigid;
mod sampling;
mod skinning;

pub use correlation::*;
pub use field::*;
pub use fold::*;
pub use labels::*;
pub use nonrigid::*;
pub use reduce::*;
pub use regions::*;
pub use rigid::*;
pub use sampling::*;
pub use skinning::*;

/// Rows 0..3 of a 4×4 affine as f32 [x, y, z, w] (w = translation).
fn rows(m: &Affine) -> [[f32; 4]; 3] {
    std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)] as f32))
}

/// Rows of the linear part only (w = 0).
fn linear_rows(m: &nalgebra::Matrix3<f64>) -> [[f32; 4]; 3] {
    std::array::from_fn(|r| [m[(r, 0)] as f32, m[(r, 1)] as f32, m[(r, 2)] as f32, 0.0])
}

/// Rows of the inverse of `grid`'s linear part (d(index)/d(world mm)), whole numbers snapped.
fn mm_to_index_rows(grid: &Grid) -> [[f32; 4]; 3] {
    let inv = snap_to_integers(&grid.world_to_voxel_affine());
    std::array::from_fn(|r| {
        [
            inv[(r, 0)] as f32,
            inv[(r, 1)] as f32,
            inv[(r, 2)] as f32,
            0.0,
        ]
    })
}

/// nx · ny · nz of a parameter struct's [nx, ny, nz, _].
fn count(dims: &[u32; 4]) -> usize {
    dims[..3].iter().map(|&n| n as usize).product()
}

/// [values, values per chunk, chunks, w]: how a reduction splits `values` into chunks.
fn chunking(values: usize, per_chunk: usize, w: u32) -> [u32; 4] {
    [
        values as u32,
        per_chunk as u32,
        values.div_ceil(per_chunk) as u32,
        w,
    ]
}

fn dims4(g: &Grid, w: u32) -> [u32; 4] {
    padded(g.dims, w)
}

/// Three counts as a vec4<u32>, `w` last.
fn padded(v: [usize; 3], w: u32) -> [u32; 4] {
    [v[0] as u32, v[1] as u32, v[2] as u32, w]
}

/// Removes the 1e-16-sized noise an f64 inverse leaves on entries that are whole numbers, so a
/// target grid equal to the source grid maps every voxel exactly onto itself.
fn snap_to_integers(m: &Affine) -> Affine {
    m.map(|v| {
        if (v - v.round()).abs() < 1e-9 {
            v.round()
        } else {
            v
        }
    })
}
