//! Similarity per cell: the SSD between two volumes summed over each cell of a cell grid.
//!
//! Both backends produce the same partial sums (one per (x, z) column and y-cell, see
//! shaders/nonrigid/ssd_cells.wgsl); this module folds them in f64 in one fixed order, so the per-cell
//! sums do not depend on thread scheduling.

use crate::error::{Error, Result};

/// Per-cell sums of squared differences.
#[derive(Clone, Debug, PartialEq)]
pub struct CellSsd {
    /// Cells along x, y, z.
    pub cells: [usize; 3],
    /// Sum of squared differences per cell, x fastest.
    pub sum: Vec<f64>,
    /// Voxels per cell, x fastest.
    pub count: Vec<u64>,
}

impl CellSsd {
    /// SSD over the whole volume.
    pub fn total(&self) -> f64 {
        self.sum.iter().sum()
    }

    /// Mean squared difference per cell (0 for empty cells).
    pub fn mean(&self) -> Vec<f64> {
        self.sum
            .iter()
            .zip(&self.count)
            .map(|(s, &n)| if n > 0 { s / n as f64 } else { 0.0 })
            .collect()
    }
}

/// The cell along an axis of `n` voxels that voxel `i` falls in (`cells` cells).
pub fn cell_of(i: usize, n: usize, cells: usize) -> usize {
    i * cells / n
}

/// Checks a cell grid against volume dims.
pub fn check_cells(dims: [usize; 3], cells: [usize; 3]) -> Result<()> {
    for a in 0..3 {
        if cells[a] == 0 || cells[a] > dims[a] {
            return Err(Error::InvalidInput(format!(
                "cannot split {} voxels into {} cells along axis {a}",
                dims[a], cells[a]
            )));
        }
    }
    Ok(())
}

/// Folds column partial sums (layout of shaders/nonrigid/ssd_cells.wgsl over the whole volume:
/// partial[(z * nx + x) * cy + c]) into per-cell sums, in f64, always in the same order.
pub fn fold_ssd_partials(dims: [usize; 3], cells: [usize; 3], partial: &[f32]) -> CellSsd {
    let [nx, ny, nz] = dims;
    let [cx, cy, cz] = cells;
    let mut sum = vec![0.0f64; cx * cy * cz];
    for z in 0..nz {
        let kz = cell_of(z, nz, cz);
        for x in 0..nx {
            let kx = cell_of(x, nx, cx);
            for c in 0..cy {
                sum[kx + cx * (c + cy * kz)] += partial[(z * nx + x) * cy + c] as f64;
            }
        }
    }
    let per_axis = |n: usize, c: usize| {
        let mut counts = vec![0u64; c];
        for i in 0..n {
            counts[cell_of(i, n, c)] += 1;
        }
        counts
    };
    let (kx, ky, kz) = (per_axis(nx, cx), per_axis(ny, cy), per_axis(nz, cz));
    let mut count = vec![0u64; cx * cy * cz];
    for z in 0..cz {
        for y in 0..cy {
            for x in 0..cx {
                count[x + cx * (y + cy * z)] = kx[x] * ky[y] * kz[z];
            }
        }
    }
    CellSsd { cells, sum, count }
}

/// Pearson correlation of two equally long sequences over the voxels where `mask` is true
/// (f64 accumulation); 0 when either side is constant.
pub fn correlation(a: &[f32], b: &[f32], mask: impl Fn(usize) -> bool) -> f64 {
    let (mut n, mut sa, mut sb) = (0.0f64, 0.0f64, 0.0f64);
    for i in (0..a.len()).filter(|&i| mask(i)) {
        n += 1.0;
        sa += a[i] as f64;
        sb += b[i] as f64;
    }
    if n == 0.0 {
        return 0.0;
    }
    let (ma, mb) = (sa / n, sb / n);
    let (mut cov, mut va, mut vb) = (0.0f64, 0.0f64, 0.0f64);
    for i in (0..a.len()).filter(|&i| mask(i)) {
        let (da, db) = (a[i] as f64 - ma, b[i] as f64 - mb);
        cov += da * db;
        va += da * da;
        vb += db * db;
    }
    if va == 0.0 || vb == 0.0 {
        0.0
    } else {
        cov / (va * vb).sqrt()
    }
}

/// Dice overlap 2|A∩B| / (|A| + |B|) of the voxels equal to `label` in two label maps
/// (labels as exact small integers in f32 or u16). 1 when both are empty.
pub fn dice<T: PartialEq + Copy>(a: &[T], b: &[T], label: T) -> f64 {
    let (mut both, mut na, mut nb) = (0usize, 0usize, 0usize);
    for (x, y) in a.iter().zip(b) {
        let (ia, ib) = (*x == label, *y == label);
        na += ia as usize;
        nb += ib as usize;
        both += (ia && ib) as usize;
    }
    if na + nb == 0 {
        1.0
    } else {
        2.0 * both as f64 / (na + nb) as f64
    }
}
