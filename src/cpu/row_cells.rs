//! The cells a row of points falls in, for the kernels that sample a volume trilinearly a row
//! of voxels at a time (compose, resample, the lattice warp's sampling): per voxel of the row
//! its point, the voxels it lies between on each axis, its fraction past the first and the
//! cell's 8 corners' indices, each pass over the whole row so that it vectorises (crate::cpu's
//! notes).

use crate::sample::{
    affine_row, array_from, axis_corners, blend_corners, corner_index, inside_axis, linear_row,
};

/// One row's points and their cells, each per voxel of the row.
#[derive(Default)]
pub struct RowCells {
    /// The points' continuous indices per axis (filled by the kernel).
    pub position: [Vec<f32>; 3],
    /// Each point's fraction past its cell's first corner per axis.
    fraction: [Vec<f32>; 3],
    /// [`axis_corners`]' voxels per axis.
    ends: [[Vec<u32>; 2]; 3],
    /// The flat indices of each point's 8 corners ([`crate::sample::corners`]' order).
    pub at: [Vec<u32>; 8],
}

impl RowCells {
    /// Every lane `nx` long.
    pub fn resize(&mut self, nx: usize) {
        for lane in self.position.iter_mut().chain(&mut self.fraction) {
            lane.resize(nx, 0.0);
        }
        for lane in self.ends.iter_mut().flatten().chain(&mut self.at) {
            lane.resize(nx, 0);
        }
    }

    /// The points of row (j, k) of a grid, each voxel displaced by its vector of
    /// `displacement` (3 floats per voxel, mm), in another volume's indices: per axis a,
    /// `affine_row(to_index[a], voxel) + linear_row(mm_to_index[a], u)` (geometry.wgsl's
    /// source_index).
    #[inline(always)]
    pub fn place(
        &mut self,
        [j, k]: [u32; 2],
        (to_index, mm_to_index): ([[f32; 4]; 3], [[f32; 4]; 3]),
        displacement: &[f32],
    ) {
        for (a, position) in self.position.iter_mut().enumerate() {
            let u = displacement.chunks_exact(3);
            for (i, (q, u)) in position.iter_mut().zip(u).enumerate() {
                let p = [i as f32, j as f32, k as f32];
                *q = affine_row(to_index[a], p) + linear_row(mm_to_index[a], [u[0], u[1], u[2]]);
            }
        }
    }

    /// The cells of the first `nx` points in a volume of `dims` (clamped to it, as
    /// [`crate::sample::corner_indices`]).
    #[inline(always)]
    pub fn locate(&mut self, nx: usize, dims: [u32; 3]) {
        for (a, &n) in dims.iter().enumerate() {
            let ([lower, upper], fraction) = (&mut self.ends[a], &mut self.fraction[a][..nx]);
            let (lower, upper) = (&mut lower[..nx], &mut upper[..nx]);
            for (i, &q) in self.position[a][..nx].iter().enumerate() {
                ([lower[i], upper[i]], fraction[i]) = axis_corners(q, n);
            }
        }
        let ends = self
            .ends
            .each_ref()
            .map(|[lower, upper]| [&lower[..nx], &upper[..nx]]);
        let mut at = self.at.each_mut().map(|lane| &mut lane[..nx]);
        for i in 0..nx {
            let ends: [[u32; 2]; 3] = array_from(|a| [ends[a][0][i], ends[a][1][i]]);
            for (c, lane) in at.iter_mut().enumerate() {
                lane[i] = corner_index(c, ends, dims);
            }
        }
    }

    /// The first `nx` points' fractions per axis.
    pub fn fractions(&self, nx: usize) -> [&[f32]; 3] {
        std::array::from_fn(|a| &self.fraction[a][..nx])
    }

    /// Whether each of the first `nx` points lies inside a volume of `dims`
    /// ([`crate::sample::inside_source`]), into `inside`.
    #[inline(always)]
    pub fn inside(&self, nx: usize, dims: [u32; 3], inside: &mut Vec<bool>) {
        inside.clear();
        inside.resize(nx, true);
        for (a, &n) in dims.iter().enumerate() {
            for (inside, &q) in inside.iter_mut().zip(&self.position[a][..nx]) {
                *inside &= inside_axis(q, n);
            }
        }
    }

    /// `volume` at the 8 corners of each of the first `nx` points' cells (after
    /// [`RowCells::locate`]), into `corners`: the one pass that cannot vectorise.
    #[inline(always)]
    pub fn gather(&self, nx: usize, volume: &[f32], corners: &mut [Vec<f32>; 8]) {
        for (at, values) in self.at.iter().zip(corners) {
            values.resize(nx, 0.0);
            for (&at, value) in at[..nx].iter().zip(&mut values[..nx]) {
                *value = volume[at as usize];
            }
        }
    }

    /// The trilinear value at each of the first `nx` points from its cell's `corners` (as
    /// [`RowCells::gather`] leaves them), into `values`.
    #[inline(always)]
    pub fn blend(&self, nx: usize, corners: &[Vec<f32>; 8], values: &mut [f32]) {
        let corners: [&[f32]; 8] = std::array::from_fn(|c| &corners[c][..nx]);
        let fraction = self.fractions(nx);
        for (i, value) in values[..nx].iter_mut().enumerate() {
            let t = array_from(|a| fraction[a][i]);
            *value = blend_corners(array_from(|c| corners[c][i]), t)[0];
        }
    }
}
