//! The adaptive stage's evaluation: the RBF on the lattice, its adjoint, the lattice energy,
//! the per-cell SSD and the intensity gain.

use super::*;

/// Keep in sync with `RbfGradParams` in shaders/lattice_warp.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct RbfGradParams {
    /// Target nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Lattice nodes along x, y, z, unused.
    pub lattice_dims: [u32; 4],
    /// Lattice step along x, y, z (voxels: node a sits on voxel a · step), unused.
    pub lattice_step: [u32; 4],
    /// The moving image's nx, ny, nz, unused: the target's, or the grid it samples.
    pub moving_dims: [u32; 4],
    /// Target voxel (i, j, k) lies on the moving image's voxel stride · (i, j, k); 1 where the
    /// two share a grid. unused last.
    pub stride: [u32; 4],
    /// Rows of the inverse linear part of the moving image's grid: a displacement in mm →
    /// index delta.
    pub mm_to_index: [[f32; 4]; 3],
    /// Index-space gradient of the moving image → world gradient ((L⁻¹)ᵀ).
    pub gradient_to_world: [[f32; 4]; 3],
}

impl RbfGradParams {
    /// For a target `grid` with a lattice of `lattice_dims` nodes every `steps` voxels, the
    /// moving image on the same grid.
    pub fn new(grid: &Grid, lattice_dims: [usize; 3], steps: [usize; 3]) -> Self {
        RbfGradParams::sampling(grid, 1, lattice_dims, steps)
    }

    /// For a target grid taking every `stride`-th voxel of the moving image's `grid` per axis,
    /// from its first, with a lattice of `lattice_dims` nodes every `steps` target voxels.
    pub fn sampling(
        grid: &Grid,
        stride: usize,
        lattice_dims: [usize; 3],
        steps: [usize; 3],
    ) -> Self {
        let l: nalgebra::Matrix3<f64> = grid.affine.fixed_view::<3, 3>(0, 0).into_owned();
        let inv = l.try_inverse().expect("validated grids are invertible");
        RbfGradParams {
            dims: dims4(&grid.every(stride), 0),
            lattice_dims: padded(lattice_dims, 0),
            lattice_step: padded(steps, 0),
            moving_dims: dims4(grid, 0),
            stride: padded([stride; 3], 0),
            mm_to_index: linear_rows(&inv),
            gradient_to_world: linear_rows(&inv.transpose()),
        }
    }

    /// Voxels of the target grid.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }

    /// Rows of x (ny · nz): warp_cost writes one sum per row.
    pub fn rows(&self) -> usize {
        (self.dims[1] * self.dims[2]) as usize
    }
}

/// Keep in sync with `SplatParams` in shaders/nonrigid/lattice_splat.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SplatParams {
    /// Lattice lx, ly, lz, unused.
    pub dims: [u32; 4],
    /// Lattice step along x, y, z (voxels), unused.
    pub step: [u32; 4],
    /// Volume nx, ny, nz, unused.
    pub volume_dims: [u32; 4],
}

impl SplatParams {
    /// For a lattice of `lattice_dims` nodes every `steps` voxels over a volume of `dims`.
    pub fn new(lattice_dims: [usize; 3], steps: [usize; 3], dims: [usize; 3]) -> Self {
        SplatParams {
            dims: padded(lattice_dims, 0),
            step: padded(steps, 0),
            volume_dims: padded(dims, 0),
        }
    }

    /// Nodes of the lattice.
    pub fn nodes(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `RbfLatticeParams` in shaders/nonrigid/rbf_nodes.wgsl (rbf_lattice, rbf_adjoint).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct RbfLatticeParams {
    /// Lattice nodes along x, y, z, unused.
    pub lattice: [u32; 4],
    /// Lattice step along x, y, z (voxels), unused.
    pub step: [u32; 4],
    /// rbf_adjoint's chunks: nodes, nodes per chunk, chunks, unused.
    pub chunks: [u32; 4],
    /// The spline's control points.
    pub points: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 3],
}

/// Lattice nodes one rbf_adjoint invocation sums: about `nodes / 512`, so that a GPU runs
/// hundreds of chunks side by side (with 4096 nodes a chunk, the paper-size lattice made 37
/// chunks and each invocation a serial loop of f64 square roots: 2.7 ms of an evaluation's
/// 4.1 ms on an NVIDIA H200), but at least 256 (fewer partials to add) and at most 4096 (well
/// below lavapipe's 65 535 loop iterations).
fn adjoint_chunk(nodes: usize) -> usize {
    (nodes / 512).clamp(256, 4096)
}

impl RbfLatticeParams {
    /// A lattice of `lattice_dims` nodes every `steps` voxels, for a warp of `points` control
    /// points.
    pub fn new(lattice_dims: [usize; 3], steps: [usize; 3], points: usize) -> Self {
        let nodes: usize = lattice_dims.iter().product();
        RbfLatticeParams {
            lattice: padded(lattice_dims, 0),
            step: padded(steps, 0),
            chunks: chunking(nodes, adjoint_chunk(nodes), 0),
            points: points as u32,
            pad: [0; 3],
        }
    }

    /// Nodes per chunk of rbf_adjoint.
    pub fn chunk_nodes(&self) -> usize {
        self.chunks[1] as usize
    }

    /// Chunks of nodes rbf_adjoint sums separately.
    pub fn chunks(&self) -> usize {
        self.chunks[2] as usize
    }

    /// rbf_adjoint's output rows: the control points, then 4 affine rows.
    pub fn rows(&self) -> usize {
        self.points() + 4
    }

    /// Nodes in the lattice.
    pub fn nodes(&self) -> usize {
        count(&self.lattice)
    }

    /// Control points.
    pub fn points(&self) -> usize {
        self.points as usize
    }
}

/// The rows of `grid`'s voxel → world affine as the RBF kernels read them (`geometry`, 12 f64).
pub fn lattice_geometry(grid: &Grid) -> Vec<f64> {
    (0..3)
        .flat_map(|r| (0..4).map(move |c| grid.affine[(r, c)]))
        .collect()
}

/// The cubic RBF as the RBF kernels read it (`spline`): the affine part a_kc at 3k + c, then
/// per control point its position and λ.
pub fn spline_buffer(
    affine: &[[f64; 3]; 4],
    centres: &[[f64; 3]],
    lambda: &[[f64; 3]],
) -> Vec<f64> {
    let mut out: Vec<f64> = affine.iter().flatten().copied().collect();
    for (c, l) in centres.iter().zip(lambda) {
        out.extend_from_slice(c);
        out.extend_from_slice(l);
    }
    out
}

/// Most operators of a lattice energy (3 membrane + 6 bending).
pub const MAX_OPERATORS: usize = 9;
/// Most taps of one operator.
pub const MAX_TAPS: usize = 4;

/// One quadratic operator of a lattice energy: taps (node offset, coefficient) and a weight.
#[derive(Clone, Debug, PartialEq)]
pub struct Operator {
    /// Node offsets and coefficients.
    pub taps: Vec<([i32; 3], f32)>,
    /// Weight of the squared result.
    pub weight: f32,
}

/// Keep in sync with `EnergyParams` in shaders/nonrigid/lattice_energy.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct EnergyParams {
    /// Lattice nodes along x, y, z, unused.
    pub dims: [u32; 4],
    /// Factor on the splatted image gradient (1 / voxels).
    pub scale: f32,
    /// Operators (at most [`MAX_OPERATORS`]).
    pub operators: u32,
    /// Padding to 16 bytes.
    pub pad: [u32; 2],
    /// Operator o's tap t at 4 o + t: node offset, unused.
    pub taps: [[i32; 4]; MAX_OPERATORS * MAX_TAPS],
    /// Operator o's tap coefficients.
    pub coefficients: [[f32; 4]; MAX_OPERATORS],
    /// Operator o's weight, unused ×3.
    pub weights: [[f32; 4]; MAX_OPERATORS],
    /// Operator o's number of taps at [o / 4][o % 4].
    pub tap_counts: [[u32; 4]; 3],
}

impl EnergyParams {
    /// For a lattice of `dims` nodes, splatted gradients scaled by `scale`, and `operators`
    /// (at most [`MAX_OPERATORS`], each with at most [`MAX_TAPS`] taps).
    pub fn new(dims: [usize; 3], scale: f32, operators: &[Operator]) -> Self {
        assert!(
            operators.len() <= MAX_OPERATORS,
            "too many energy operators"
        );
        let mut p = EnergyParams::zeroed();
        p.dims = padded(dims, 0);
        p.scale = scale;
        p.operators = operators.len() as u32;
        for (o, op) in operators.iter().enumerate() {
            assert!(
                op.taps.len() <= MAX_TAPS,
                "too many taps in an energy operator"
            );
            // The CPU twin keeps results only for anchors on the lattice.
            assert!(
                (0..3).all(|a| {
                    let span = op.taps.iter().map(|(offset, _)| offset[a]);
                    span.clone().min() <= Some(0) && span.max() >= Some(0)
                }),
                "an energy operator's anchor must lie within its taps' span"
            );
            for (t, (offset, c)) in op.taps.iter().enumerate() {
                p.taps[MAX_TAPS * o + t] = [offset[0], offset[1], offset[2], 0];
                p.coefficients[o][t] = *c;
            }
            p.weights[o][0] = op.weight;
            p.tap_counts[o / 4][o % 4] = op.taps.len() as u32;
        }
        p
    }

    /// Lattice nodes.
    pub fn nodes(&self) -> usize {
        count(&self.dims)
    }
}

/// Keep in sync with `SsdParams` in shaders/nonrigid/ssd_cells.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct SsdParams {
    /// nx, ny, nz, unused.
    pub dims: [u32; 4],
    /// Cells along x, y, z, unused.
    pub cells: [u32; 4],
}

impl SsdParams {
    /// Parameters for an (nx, ny, nz) volume split into `cells`.
    pub fn new(dims: [usize; 3], cells: [usize; 3]) -> Self {
        SsdParams {
            dims: [dims[0] as u32, dims[1] as u32, dims[2] as u32, 0],
            cells: [cells[0] as u32, cells[1] as u32, cells[2] as u32, 0],
        }
    }

    /// Partial sums the kernel writes: nz · nx · cy.
    pub fn partials(&self) -> usize {
        (self.dims[2] * self.dims[0] * self.cells[1]) as usize
    }
}

/// Keep in sync with `GainParams` in shaders/nonrigid/gain.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct GainParams {
    /// nx, ny, nz of the grid written, unused.
    pub dims: [u32; 4],
    /// nx, ny, nz of the smoothed grid, unused.
    pub coarse_dims: [u32; 4],
    /// Voxel index of the grid written → continuous index of the smoothed grid.
    pub to_coarse: [[f32; 4]; 3],
    /// Smoothed energy at or below which the gain is 1.
    pub floor: f32,
    /// Most gain: ratios are kept within this factor of 1.
    pub most: f32,
    /// Padding to 16 bytes.
    pub pad: [u32; 2],
}

impl GainParams {
    /// For kernels writing `grid`, the gain smoothed on `coarse`, ratios kept within a factor
    /// `most` of 1 and set to 1 where the smoothed energy is at or below `floor`.
    pub fn new(grid: &Grid, coarse: &Grid, floor: f32, most: f32) -> Self {
        GainParams {
            dims: dims4(grid, 0),
            coarse_dims: dims4(coarse, 0),
            to_coarse: rows(&(coarse.world_to_voxel_affine() * grid.affine)),
            floor,
            most,
            pad: [0; 2],
        }
    }

    /// Voxels of the grid written.
    pub fn voxels(&self) -> usize {
        count(&self.dims)
    }
}
