//! Images on a voxel grid placed in world space.
//!
//! A [`Grid`] is the voxel lattice plus the 4×4 affine that maps a voxel index (i, j, k) to
//! world millimetres in NIfTI RAS+ (+x to the subject's Right, +y Anterior, +z Superior).
//! Voxels are stored x-fastest
//! (index = i + nx·(j + ny·k)), the NIfTI on-disk order, so files map to memory without shuffles.

use crate::error::{Error, Result};
use nalgebra::{Matrix4, Vector4};

/// A voxel→world affine (RAS+ mm), in f64 so repeated composition loses nothing measurable.
pub type Affine = Matrix4<f64>;

/// The voxel lattice of an image and where it sits in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Voxels along i, j, k.
    pub dims: [usize; 3],
    /// Voxel index → world RAS mm.
    pub affine: Affine,
}

impl Grid {
    /// A grid; checks that it has voxels and an invertible, finite affine.
    pub fn new(dims: [usize; 3], affine: Affine) -> Result<Self> {
        let grid = Grid { dims, affine };
        grid.validate()?;
        Ok(grid)
    }

    /// Every `stride`-th voxel per axis from the first: the same origin and extent (to a voxel),
    /// voxels `stride` times as far apart.
    pub fn every(&self, stride: usize) -> Grid {
        self.every_along([stride; 3])
    }

    /// Every `strides[a]`-th voxel along each axis a from the first (each stride at least 1).
    pub fn every_along(&self, strides: [usize; 3]) -> Grid {
        let mut affine = self.affine;
        for (c, &stride) in strides.iter().enumerate() {
            for r in 0..3 {
                affine[(r, c)] *= stride as f64;
            }
        }
        Grid {
            dims: std::array::from_fn(|a| (self.dims[a] - 1) / strides[a] + 1),
            affine,
        }
    }

    /// Why this grid cannot be used, if it cannot.
    pub fn validate(&self) -> Result<()> {
        if self.dims.contains(&0) {
            return Err(Error::InvalidInput(format!(
                "grid has an empty dimension: {:?}",
                self.dims
            )));
        }
        if self.affine.iter().any(|v| !v.is_finite()) {
            return Err(Error::InvalidInput("affine has non-finite entries".into()));
        }
        let spacing = self.spacing();
        if spacing.iter().any(|&s| s < 1e-6) {
            return Err(Error::InvalidInput(format!(
                "voxel spacing {spacing:?} mm has a zero axis"
            )));
        }
        if self.affine.fixed_view::<3, 3>(0, 0).determinant().abs() < 1e-12 {
            return Err(Error::InvalidInput("affine is singular".into()));
        }
        Ok(())
    }

    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// True for a grid without voxels (never true for a validated grid).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Flat index of voxel (i, j, k).
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// Length in mm of one step along each voxel axis.
    pub fn spacing(&self) -> [f64; 3] {
        let m = &self.affine;
        std::array::from_fn(|c| {
            (m[(0, c)] * m[(0, c)] + m[(1, c)] * m[(1, c)] + m[(2, c)] * m[(2, c)]).sqrt()
        })
    }

    /// The smallest of the three voxel spacings (mm).
    pub fn finest_spacing(&self) -> f64 {
        self.spacing().into_iter().fold(f64::INFINITY, f64::min)
    }

    /// World position (RAS mm) of a continuous voxel index.
    pub fn voxel_to_world(&self, ijk: [f64; 3]) -> [f64; 3] {
        let p = self.affine * Vector4::new(ijk[0], ijk[1], ijk[2], 1.0);
        [p.x, p.y, p.z]
    }

    /// World position (RAS mm) of the voxel with flat index n (x fastest).
    pub fn world_of(&self, n: usize) -> nalgebra::Vector3<f64> {
        let [nx, ny, _] = self.dims;
        let p = self.affine
            * Vector4::new(
                (n % nx) as f64,
                ((n / nx) % ny) as f64,
                (n / (nx * ny)) as f64,
                1.0,
            );
        nalgebra::Vector3::new(p.x, p.y, p.z)
    }

    /// World (RAS mm) → continuous voxel index.
    pub fn world_to_voxel_affine(&self) -> Affine {
        self.affine
            .try_inverse()
            .expect("validated grids have invertible affines")
    }

    /// True when world point `p` lies inside the field of view: within half a voxel of the
    /// outermost voxel centres.
    pub fn contains(&self, p: &nalgebra::Vector3<f64>) -> bool {
        self.holds_index(&(self.world_to_voxel_affine() * p.push(1.0)))
    }

    /// True when the continuous voxel index `q` lies within half a voxel of the grid.
    fn holds_index(&self, q: &nalgebra::Vector4<f64>) -> bool {
        (0..3).all(|a| q[a] > -0.5 && q[a] < self.dims[a] as f64 - 0.5)
    }

    /// Share of this grid's voxel centres (sampled every few voxels) that lie inside `other`'s
    /// field of view: 0 when the two scans do not overlap in the world.
    pub fn share_inside(&self, other: &Grid) -> f64 {
        let to_other = other.world_to_voxel_affine() * self.affine;
        let stride = self.dims.map(|d| (d / 16).max(1));
        let (mut inside, mut total) = (0usize, 0usize);
        for k in (0..self.dims[2]).step_by(stride[2]) {
            for j in (0..self.dims[1]).step_by(stride[1]) {
                for i in (0..self.dims[0]).step_by(stride[0]) {
                    let q = to_other * nalgebra::Vector4::new(i as f64, j as f64, k as f64, 1.0);
                    total += 1;
                    if other.holds_index(&q) {
                        inside += 1;
                    }
                }
            }
        }
        inside as f64 / total.max(1) as f64
    }

    /// True when both grids have the same dims and affines equal to `tol` (mm).
    pub fn same_as(&self, other: &Grid, tol: f64) -> bool {
        self.dims == other.dims
            && self
                .affine
                .iter()
                .zip(other.affine.iter())
                .all(|(a, b)| (a - b).abs() <= tol)
    }

    /// Orientation code in the nibabel sense ("RAS", "LPI", "PIR" ...): for each voxel axis,
    /// the world direction it points most towards.
    pub fn orientation_code(&self) -> String {
        let m = &self.affine;
        (0..3)
            .map(|c| {
                let col = [m[(0, c)], m[(1, c)], m[(2, c)]];
                let (axis, v) = col
                    .iter()
                    .enumerate()
                    .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
                    .map(|(a, v)| (a, *v))
                    .unwrap_or((0, 0.0));
                let (pos, neg) = [('R', 'L'), ('A', 'P'), ('S', 'I')][axis];
                if v >= 0.0 {
                    pos
                } else {
                    neg
                }
            })
            .collect()
    }
}

/// Voxel values on a grid. `T` is f32 for intensities, u16 for labels, `[f32; 3]` for
/// displacement vectors (world mm).
#[derive(Clone, Debug, PartialEq)]
pub struct Image<T> {
    /// Where the voxels are.
    pub grid: Grid,
    /// One value per voxel, x fastest.
    pub data: Vec<T>,
}

/// A scalar intensity volume.
pub type Volume = Image<f32>;
/// An integer label map (codes in ARCHITECTURE.md: 0 outside, 1 soft tissue, 2 femur ...).
pub type Labels = Image<u16>;
/// A dense displacement field in world RAS mm on a (target) grid: the vector at target point
/// p is d such that p + d is the corresponding source point.
pub type Field = Image<[f32; 3]>;

impl<T: Clone> Image<T> {
    /// An image with every voxel set to `value`.
    pub fn filled(grid: Grid, value: T) -> Self {
        let n = grid.len();
        Image {
            grid,
            data: vec![value; n],
        }
    }

    /// An image from data; checks the length matches the grid.
    pub fn from_data(grid: Grid, data: Vec<T>) -> Result<Self> {
        if data.len() != grid.len() {
            return Err(Error::InvalidInput(format!(
                "{} values for a grid of {:?} = {} voxels",
                data.len(),
                grid.dims,
                grid.len()
            )));
        }
        Ok(Image { grid, data })
    }
}

impl Volume {
    /// Smallest and largest voxel value.
    pub fn range(&self) -> (f32, f32) {
        self.data
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(v), hi.max(v))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_of_common_affines() {
        let ras = Grid::new([2, 2, 2], Affine::identity()).unwrap();
        assert_eq!(ras.orientation_code(), "RAS");
        let mut lpi = Affine::identity();
        lpi[(0, 0)] = -1.0;
        lpi[(1, 1)] = -1.0;
        lpi[(2, 2)] = -2.0;
        assert_eq!(Grid::new([2, 2, 2], lpi).unwrap().orientation_code(), "LPI");
    }

    #[test]
    fn zero_spacing_is_rejected() {
        let mut a = Affine::identity();
        a[(2, 2)] = 0.0;
        let err = Grid::new([2, 2, 2], a).unwrap_err().to_string();
        assert!(err.contains("zero axis"), "{err}");
    }
}
