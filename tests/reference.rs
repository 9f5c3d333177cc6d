//! CPU twins against closed forms.

mod common;

use common::*;
use posereg::abi::Interpolation;
use posereg::abi::{Blending, BoneBlend, SumParams};
use posereg::backend::box_sums;
use posereg::backend::prelude::*;
use posereg::backend::DeviceImage;
use posereg::cpu::CpuBackend;
use posereg::volume::{Affine, Grid, Image};
use std::sync::Arc;

/// A linear ramp with dyadic coefficients: every value and every trilinear weight used below
/// is exactly representable in f32, so trilinear interpolation of it is exact, not approximate.
fn ramp(grid: &Grid) -> posereg::Volume {
    let [nx, ny, nz] = grid.dims;
    let mut data = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                data.push(0.5 * i as f32 + 0.25 * j as f32 + 2.0 * k as f32 + 3.0);
            }
        }
    }
    Image::from_data(grid.clone(), data).unwrap()
}

#[test]
fn trilinear_of_a_linear_ramp_is_exact() {
    let grid = Grid::new([9, 8, 7], Affine::identity()).unwrap();
    let source = ramp(&grid);
    // A shift in eighths of a voxel keeps every coordinate and weight dyadic.
    let shift = [0.125f32, -0.375, 0.25];
    let warped = resample_volume(
        &CpuBackend,
        &source,
        &constant_field(&grid, shift),
        -1.0,
        Interpolation::Linear,
    )
    .unwrap();
    let [nx, ny, nz] = grid.dims;
    let mut inside = 0;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let q = [
                    i as f32 + shift[0],
                    j as f32 + shift[1],
                    k as f32 + shift[2],
                ];
                let v = warped.data[grid.index(i, j, k)];
                // Inside the hull of voxel centres the ramp is reproduced exactly.
                if q.iter()
                    .zip(grid.dims)
                    .all(|(q, n)| *q >= 0.0 && *q <= (n - 1) as f32)
                {
                    assert_eq!(
                        v,
                        0.5 * q[0] + 0.25 * q[1] + 2.0 * q[2] + 3.0,
                        "at {i},{j},{k}"
                    );
                    inside += 1;
                }
            }
        }
    }
    assert!(inside > grid.len() / 2);
}

#[test]
fn ramp_through_oblique_grids_matches_the_world_ramp() {
    // Source and target on different oblique grids: the sample at a target voxel must be the
    // source ramp evaluated at that voxel's world point mapped into the source, computed in f64.
    let source_grid = oblique_grid([20, 18, 16]);
    let target_grid = Grid::new([11, 9, 7], {
        let mut a = Affine::identity();
        a[(0, 0)] = 1.3;
        a[(1, 1)] = 0.8;
        a[(2, 2)] = 1.9;
        a[(0, 3)] = -12.0;
        a[(1, 3)] = 10.0;
        a[(2, 3)] = 12.0;
        a
    })
    .unwrap();
    let source = ramp(&source_grid);
    let field = constant_field(&target_grid, [0.7, -0.4, 1.1]);
    let warped = resample_volume(
        &CpuBackend,
        &source,
        &field,
        f32::MIN,
        Interpolation::Linear,
    )
    .unwrap();
    let to_source = source_grid.world_to_voxel_affine();
    let mut checked = 0;
    for k in 0..7 {
        for j in 0..9 {
            for i in 0..11 {
                let w = target_grid.voxel_to_world([i as f64, j as f64, k as f64]);
                let p = nalgebra::Vector4::new(w[0] + 0.7, w[1] - 0.4, w[2] + 1.1, 1.0);
                let q = to_source * p;
                let v = warped.data[target_grid.index(i, j, k)];
                let inner = [q.x, q.y, q.z]
                    .iter()
                    .zip(source_grid.dims)
                    .all(|(q, n)| *q >= 0.0 && *q <= (n - 1) as f64);
                if inner {
                    let expected = 0.5 * q.x + 0.25 * q.y + 2.0 * q.z + 3.0;
                    assert!((v as f64 - expected).abs() < 1e-3, "{v} vs {expected}");
                    checked += 1;
                } else if v != f32::MIN {
                    // Within half a voxel of the hull: clamped to the edge, never garbage.
                    assert!(v.is_finite());
                }
            }
        }
    }
    assert!(checked > 40, "only {checked} voxels inside");
}

#[test]
fn integer_voxel_shift_moves_values_exactly() {
    let grid = Grid::new([10, 9, 8], {
        let mut a = Affine::identity();
        a[(0, 0)] = 2.0;
        a
    })
    .unwrap();
    let source = smooth_volume(&grid, 3);
    // 4 mm along x is exactly 2 voxels of 2 mm.
    let warped = resample_volume(
        &CpuBackend,
        &source,
        &constant_field(&grid, [4.0, 0.0, 0.0]),
        -7.0,
        Interpolation::Linear,
    )
    .unwrap();
    for k in 0..8 {
        for j in 0..9 {
            for i in 0..10 {
                let v = warped.data[grid.index(i, j, k)];
                let expected = if i + 2 < 10 {
                    source.data[grid.index(i + 2, j, k)]
                } else {
                    -7.0
                };
                assert_eq!(v, expected, "at {i},{j},{k}");
            }
        }
    }
}

#[test]
fn points_fully_outside_get_the_background() {
    let grid = oblique_grid([7, 6, 5]);
    let source = smooth_volume(&grid, 1);
    let warped = resample_volume(
        &CpuBackend,
        &source,
        &constant_field(&grid, [500.0, 0.0, 0.0]),
        42.0,
        Interpolation::Linear,
    )
    .unwrap();
    assert!(warped.data.iter().all(|&v| v == 42.0));
}

#[test]
fn ssd_of_a_known_pair() {
    // 7 voxels split into 3 cells gives cells of 3, 2 and 2 voxels (voxel i in cell i*3/7).
    let grid = Grid::new([7, 5, 4], Affine::identity()).unwrap();
    let a = smooth_volume(&grid, 11);
    let b = smooth_volume(&grid, 12);
    let cells = [3, 2, 2];
    let ssd = cell_ssd(&CpuBackend, (&a, &b, &vec![1.0; grid.len()]), cells);
    let mut expected = vec![0.0f64; 12];
    let mut counts = vec![0u64; 12];
    for k in 0..4 {
        for j in 0..5 {
            for i in 0..7 {
                let c = i * 3 / 7 + 3 * (j * 2 / 5 + 2 * (k * 2 / 4));
                let d = a.data[grid.index(i, j, k)] as f64 - b.data[grid.index(i, j, k)] as f64;
                expected[c] += d * d;
                counts[c] += 1;
            }
        }
    }
    assert_eq!(ssd.count, counts);
    assert_eq!(ssd.count[..3], [3 * 3 * 2, 2 * 3 * 2, 2 * 3 * 2]);
    for (got, want) in ssd.sum.iter().zip(&expected) {
        assert!(
            (got - want).abs() <= 1e-5 * want.max(1.0),
            "{got} vs {want}"
        );
    }
    let total: f64 = expected.iter().sum();
    assert!((ssd.total() - total).abs() <= 1e-5 * total);
    // Identical volumes: exactly zero everywhere.
    let zero = cell_ssd(&CpuBackend, (&a, &a, &vec![1.0; grid.len()]), cells);
    assert!(zero.sum.iter().all(|&s| s == 0.0));
}

#[test]
fn cell_grids_finer_than_the_volume_are_refused() {
    use posereg::images::metric::check_cells;
    assert!(check_cells([4, 4, 4], [5, 1, 1]).is_err());
    assert!(check_cells([4, 4, 4], [0, 1, 1]).is_err());
    assert!(check_cells([4, 4, 4], [4, 1, 2]).is_ok());
}

/// jacobian.wgsl read voxel by voxel: central differences (one-sided at the faces, 0 along an
/// axis one voxel long), the rows of I + du/dx and their determinant, in the shader's order.
fn jacobian_voxel_by_voxel(grid: &Grid, field: &[f32]) -> Vec<f32> {
    let m = posereg::abi::JacobianParams::new(grid).mm_to_index;
    let [nx, ny, nz] = grid.dims;
    let u = |i: usize, j: usize, k: usize| {
        let n = 3 * (i + nx * (j + ny * k));
        [field[n], field[n + 1], field[n + 2]]
    };
    let difference = |lo: [f32; 3], hi: [f32; 3], c: usize, n: usize| -> [f32; 3] {
        match n {
            1 => [0.0; 3],
            _ if c == 0 || c == n - 1 => std::array::from_fn(|a| hi[a] - lo[a]),
            _ => std::array::from_fn(|a| (hi[a] - lo[a]) * 0.5),
        }
    };
    let mut det = Vec::with_capacity(grid.len());
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let dx = difference(u(i.max(1) - 1, j, k), u((i + 1).min(nx - 1), j, k), i, nx);
                let dy = difference(u(i, j.max(1) - 1, k), u(i, (j + 1).min(ny - 1), k), j, ny);
                let dz = difference(u(i, j, k.max(1) - 1), u(i, j, (k + 1).min(nz - 1)), k, nz);
                let r: [[f32; 3]; 3] = std::array::from_fn(|r| {
                    std::array::from_fn(|s| {
                        let identity = if r == s { 1.0 } else { 0.0 };
                        dx[r] * m[0][s] + dy[r] * m[1][s] + dz[r] * m[2][s] + identity
                    })
                });
                det.push(
                    r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
                        - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
                        + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]),
                );
            }
        }
    }
    det
}

#[test]
fn jacobian_rows_give_the_shaders_voxels_to_the_bit() {
    // The twin takes a row's differences at once; each voxel must still be the shader's
    // operations in its order, faces and axes one voxel long included.
    for dims in [[13usize, 11, 7], [5, 1, 3], [1, 4, 2], [2, 2, 9]] {
        let grid = oblique_grid(dims);
        let field = smooth_field(&grid, 7, 5.0);
        let flat: Vec<f32> = field.data.iter().flatten().copied().collect();
        let want = jacobian_voxel_by_voxel(&grid, &flat);
        let got = host_determinant(&CpuBackend, &field).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&got), bits(&want), "{dims:?}");
    }
}

#[test]
fn jacobian_of_a_linear_field_is_its_determinant() {
    // u(x) = B x in world mm has x + u(x) = (I + B) x: det(I + B) at every voxel, borders
    // included (one-sided differences are exact for a linear field), on an oblique grid.
    let grid = oblique_grid([9, 8, 6]);
    let b = nalgebra::Matrix3::new(0.10, -0.05, 0.02, 0.03, -0.20, 0.04, 0.01, 0.06, 0.15);
    let field: posereg::Field = Image::from_data(
        grid.clone(),
        (0..grid.len())
            .map(|n| {
                let w =
                    grid.voxel_to_world([(n % 9) as f64, ((n / 9) % 8) as f64, (n / 72) as f64]);
                let u = b * nalgebra::Vector3::new(w[0], w[1], w[2]);
                [u.x as f32, u.y as f32, u.z as f32]
            })
            .collect(),
    )
    .unwrap();
    let expected = (nalgebra::Matrix3::identity() + b).determinant();
    let det = host_determinant(&CpuBackend, &field).unwrap();
    for v in &det {
        assert!((*v as f64 - expected).abs() < 1e-4, "{v} vs {expected}");
    }
    // A fold: x -> -x along the first index axis (u = -2x) has a negative determinant.
    let flip: posereg::Field = Image::from_data(
        grid.clone(),
        (0..grid.len())
            .map(|n| {
                let w =
                    grid.voxel_to_world([(n % 9) as f64, ((n / 9) % 8) as f64, (n / 72) as f64]);
                [-2.0 * w[0] as f32, 0.0, 0.0]
            })
            .collect(),
    )
    .unwrap();
    assert!(host_determinant(&CpuBackend, &flip)
        .unwrap()
        .iter()
        .all(|&v| v < 0.0));
}

#[test]
fn nearest_neighbour_keeps_label_codes() {
    let grid = Grid::new([6, 5, 4], Affine::identity()).unwrap();
    let labels: posereg::Volume =
        Image::from_data(grid.clone(), (0..120).map(|i| (i % 5) as f32).collect()).unwrap();
    // A shift of 0.4 voxel rounds back to the same voxel; 0.6 to the next one.
    let same = resample_volume(
        &CpuBackend,
        &labels,
        &constant_field(&grid, [0.4, 0.0, 0.0]),
        0.0,
        Interpolation::Nearest,
    )
    .unwrap();
    assert_eq!(same.data, labels.data);
    let next = resample_volume(
        &CpuBackend,
        &labels,
        &constant_field(&grid, [0.6, 0.0, 0.0]),
        99.0,
        Interpolation::Nearest,
    )
    .unwrap();
    for (n, v) in next.data.iter().enumerate() {
        // The last column lands 0.1 voxel beyond the half-voxel margin: background.
        let expected = if n % 6 == 5 { 99.0 } else { labels.data[n + 1] };
        assert_eq!(*v, expected, "voxel {n}");
    }
}

#[test]
fn pyramid_keeps_constants_and_linear_ramps() {
    // The binomial kernel sums to one (constants stay) and is symmetric about the coarse voxel
    // centre (a ramp is sampled at the coarse centres), away from the clamped faces.
    let grid = Grid::new([20, 18, 16], Affine::identity()).unwrap();
    let (coarse, factors) = posereg::images::pyramid::next_level_grid(&grid).unwrap();
    assert_eq!(factors, [2, 2, 2]);
    let constant = Image::filled(grid.clone(), 7.5f32);
    let down = one_level_down(&CpuBackend, &constant);
    assert!(down.grid.same_as(&coarse, 1e-9));
    assert!(down.data.iter().all(|&v| (v - 7.5).abs() < 1e-5));
    let ramp = ramp(&grid);
    let down = one_level_down(&CpuBackend, &ramp);
    let to_fine = grid.world_to_voxel_affine();
    for k in 1..coarse.dims[2] - 1 {
        for j in 1..coarse.dims[1] - 1 {
            for i in 1..coarse.dims[0] - 1 {
                let w = coarse.voxel_to_world([i as f64, j as f64, k as f64]);
                let q = to_fine * nalgebra::Vector4::new(w[0], w[1], w[2], 1.0);
                let expected = 0.5 * q.x + 0.25 * q.y + 2.0 * q.z + 3.0;
                let v = down.data[coarse.index(i, j, k)] as f64;
                assert!((v - expected).abs() < 1e-4, "{v} vs {expected}");
            }
        }
    }
}

#[test]
fn rigid_gradient_matches_finite_differences() {
    // Cost C(δ) = Σ r² at motion small_motion(δ, c)·M; the kernel's Jᵀr is ½ ∂C/∂δ at δ = 0.
    let grid = oblique_grid([26, 22, 18]);
    let source = smooth_volume(&grid, 21);
    let target = smooth_volume(&grid, 22);
    let mask: posereg::Volume = Image::filled(grid.clone(), 1.0);
    let base = posereg::init::rigid::small_motion(
        &nalgebra::Vector6::new(0.03, 0.02, -0.04, 0.8, -0.5, 0.3),
        &nalgebra::Vector3::zeros(),
    );
    // Keep only voxels well inside the target under every perturbed motion, so the set of
    // contributing voxels does not change between the finite-difference evaluations.
    let mut inner = mask.clone();
    let d = grid.dims;
    for n in 0..grid.len() {
        let (i, j, k) = (n % d[0], (n / d[0]) % d[1], n / (d[0] * d[1]));
        if i < 4 || j < 4 || k < 4 || i + 4 >= d[0] || j + 4 >= d[1] || k + 4 >= d[2] {
            inner.data[n] = 0.0;
        }
    }
    let centre = nalgebra::Vector3::new(-15.0, 12.0, 10.0);
    let up = |v: &posereg::Volume| DeviceImage::upload(&CpuBackend, "test", v.clone()).unwrap();
    let (source, inner, target) = (up(&source), up(&inner), up(&target));
    let level = posereg::init::rigid::BoneLevel {
        source: &source,
        mask: &inner,
        target: &target,
    };
    let system = |m: &posereg::Affine| {
        posereg::init::rigid::normal_equations(&CpuBackend, &level, m, &centre)
    };
    let eq = system(&base).unwrap();
    let cost = |delta: nalgebra::Vector6<f64>| {
        let at = system(&(posereg::init::rigid::small_motion(&delta, &centre) * base)).unwrap();
        (at.ssd, at.count)
    };
    let n0 = cost(nalgebra::Vector6::zeros()).1;
    for k in 0..6 {
        let eps = if k < 3 { 1e-3 } else { 1e-2 };
        let mut e = nalgebra::Vector6::zeros();
        e[k] = eps;
        let (plus, n_plus) = cost(e);
        let (minus, n_minus) = cost(-e);
        assert_eq!((n_plus, n_minus), (n0, n0), "voxel set changed");
        let fd = (plus - minus) / (2.0 * eps);
        let analytic = 2.0 * eq.jtr[k];
        assert!(
            (fd - analytic).abs() <= 1e-2 * analytic.abs().max(1.0),
            "parameter {k}: finite difference {fd} vs analytic {analytic}"
        );
    }
}

#[test]
fn skin_blend_inverts_a_common_rigid_motion_exactly() {
    // When every bone makes the same motion M the blend is M itself, whatever the weights: the
    // field must be M⁻¹p − p with (near) zero residual.
    let grid = oblique_grid([11, 10, 9]);
    let bones = 2;
    let distances: Vec<f32> = (0..grid.len() * bones)
        .map(|k| 1.0 + (k % 13) as f32)
        .collect();
    let weights = skin_weights(&CpuBackend, &distances, &grid, bones, 4).unwrap();
    for w in weights.chunks(bones) {
        assert!(
            (w.iter().sum::<f32>() - 1.0).abs() < 1e-5,
            "partition of unity"
        );
    }
    let m = posereg::init::rigid::small_motion(
        &nalgebra::Vector6::new(0.3, -0.2, 0.5, 4.0, -2.0, 1.0),
        &nalgebra::Vector3::new(1.0, 2.0, 3.0),
    );
    let target = oblique_grid([7, 6, 5]);
    let inv = m.try_inverse().unwrap();
    // Soft tissue everywhere, then a label grid where every voxel is bone 1: both blend to M,
    // linearly or by dual quaternions.
    for (bone_of_voxel, blending) in [
        (vec![0.0f32; grid.len()], Blending::Linear),
        (vec![2.0f32; grid.len()], Blending::Linear),
        (vec![0.0f32; grid.len()], Blending::DualQuaternion),
    ] {
        let blend = BoneBlend {
            motions: vec![m, m],
            blending,
            iterations: 4,
        };
        let out = skin_blend(
            &CpuBackend,
            &weights,
            &grid,
            &bone_of_voxel,
            &grid,
            &target,
            &blend,
        )
        .unwrap();
        for n in 0..target.len() {
            let w = target.world_of(n);
            let q = inv * nalgebra::Vector4::new(w[0], w[1], w[2], 1.0);
            for a in 0..3 {
                assert!((out[4 * n + a] as f64 - (q[a] - w[a])).abs() < 1e-3);
            }
            assert!(out[4 * n + 3] < 1e-3, "residual {}", out[4 * n + 3]);
        }
    }
}

#[test]
fn dual_quaternion_blending_turns_halfway_where_linear_blending_shortens_the_radius() {
    // Two bones, one still and one turned θ about the z axis through the origin, weighted ½
    // each everywhere. The linear blend B(x) = ½(x + R_θ x) turns by θ/2 and shrinks distances
    // to the axis by cos(θ/2) (z unchanged); the dual-quaternion blend is the rotation by θ/2
    // itself. The inverted fields must be exactly those maps' inverses.
    let grid = Grid::new(
        [9, 8, 7],
        Affine::identity().append_translation(&nalgebra::Vector3::new(5.0, -3.0, 1.0)),
    )
    .unwrap();
    let distances = vec![2.0f32; grid.len() * 2];
    let weights = skin_weights(&CpuBackend, &distances, &grid, 2, 2).unwrap();
    let theta = 70f64.to_radians();
    let turn = |angle: f64| {
        nalgebra::Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), angle).to_homogeneous()
    };
    let soft_tissue = vec![0.0f32; grid.len()];
    let half = turn(-theta / 2.0);
    let shrink = (theta / 2.0).cos();
    for (blending, inverse) in [
        (
            Blending::Linear,
            Affine::from_diagonal(&nalgebra::Vector4::new(
                1.0 / shrink,
                1.0 / shrink,
                1.0,
                1.0,
            )) * half,
        ),
        (Blending::DualQuaternion, half),
    ] {
        let blend = BoneBlend {
            motions: vec![Affine::identity(), turn(theta)],
            blending,
            iterations: 30,
        };
        let out = skin_blend(
            &CpuBackend,
            &weights,
            &grid,
            &soft_tissue,
            &grid,
            &grid,
            &blend,
        )
        .unwrap();
        let mut worst = 0.0f64;
        for n in 0..grid.len() {
            let p = grid.world_of(n);
            let want = inverse.fixed_view::<3, 3>(0, 0) * p - p;
            for a in 0..3 {
                worst = worst.max((out[4 * n + a] as f64 - want[a]).abs());
            }
        }
        assert!(worst < 1e-3, "{blending:?}: worst difference {worst} mm");
    }
}

/// The distance maps (three edt passes) against brute force on an anisotropic grid, for two
/// regions of a label index map at once: each voxel's distance (mm) to the nearest voxel of
/// its region, 0 inside; and the distance to the nearer of the two, in one volume.
#[test]
fn distance_maps_match_brute_force_with_anisotropic_spacing() {
    let mut a = Affine::identity();
    a[(0, 0)] = 0.5;
    a[(2, 2)] = 2.0;
    let grid = Grid::new([9, 7, 5], a).unwrap();
    let region = |n: usize| match n {
        40 | 200 => 1.0,
        3 | 250 | 251 => 2.0,
        _ => 0.0,
    };
    let index = posereg::backend::DeviceImage::<CpuBackend> {
        data: CpuBackend
            .upload("index", (0..grid.len()).map(region).collect())
            .unwrap(),
        grid: grid.clone(),
    };
    let maps = posereg::images::regions::distance_maps(&CpuBackend, &index, 2).unwrap();
    let nearest = posereg::images::regions::distance_to_nearest(&CpuBackend, &index).unwrap();
    let any_region = |n: usize| region(n) >= 1.0;
    let each_region = |r: usize| move |n: usize| region(n) == (r + 1) as f32;
    type Member<'a> = &'a dyn Fn(usize) -> bool;
    let wanted: [(&[f32], Member); 3] = [
        (&maps[..grid.len()], &each_region(0)),
        (&maps[grid.len()..], &each_region(1)),
        (&nearest, &any_region),
    ];
    for (r, (map, member)) in wanted.into_iter().enumerate() {
        let members: Vec<usize> = (0..grid.len()).filter(|&n| member(n)).collect();
        for (n, got) in map.iter().enumerate() {
            let brute = members
                .iter()
                .map(|&m| (grid.world_of(n) - grid.world_of(m)).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(
                (*got as f64 - brute).abs() < 1e-4,
                "map {r}, voxel {n}: {got} vs {brute}"
            );
        }
    }
}

/// A region's size and centroid from the moments kernel, against the voxels counted on the
/// host: an oblique grid, a smoothed-looking map with values either side of the threshold.
#[test]
fn moments_count_and_centre_a_region() {
    let grid = oblique_grid([13, 11, 7]);
    let values: Vec<f32> = (0..grid.len())
        .map(|n| ((n * 37) % 100) as f32 / 100.0)
        .collect();
    let image = posereg::backend::DeviceImage::<CpuBackend> {
        data: CpuBackend.upload("values", values.clone()).unwrap(),
        grid: grid.clone(),
    };
    let got = posereg::images::regions::moments(&CpuBackend, &image, 0.5).unwrap();
    let inside: Vec<usize> = (0..grid.len()).filter(|&n| values[n] >= 0.5).collect();
    let centroid = inside
        .iter()
        .map(|&n| grid.world_of(n))
        .sum::<nalgebra::Vector3<f64>>()
        / inside.len() as f64;
    assert_eq!(got.voxels, inside.len());
    assert!(
        (got.centroid - centroid).norm() < 1e-4,
        "{:?} vs {centroid:?}",
        got.centroid
    );
}

#[test]
fn skin_weights_are_one_inside_their_bone() {
    let grid = Grid::new([5, 4, 3], Affine::identity()).unwrap();
    let bones = 3;
    let mut distances = vec![5.0f32; grid.len() * bones];
    distances[grid.len() + 7] = 0.0; // voxel 7 is inside bone 1 (one volume per bone)
    let w = skin_weights(&CpuBackend, &distances, &grid, bones, 4).unwrap();
    assert_eq!(&w[7 * bones..8 * bones], &[0.0, 1.0, 0.0]);
    // Equal distances: equal shares.
    assert!((w[0] - 1.0 / 3.0).abs() < 1e-6);
}

#[test]
fn lattice_splat_is_the_adjoint_of_the_lattice_interpolation() {
    // <interp(L), v> over voxels == <L, splat(v)> over nodes, for random L and v: the gradient
    // the optimiser gets through the lattice is exactly the gradient of what it evaluates.
    use posereg::abi::RbfGradParams;
    use posereg::cpu::lattice_warp::{warp_at, LatticeTaps};
    let grid = oblique_grid([19, 14, 11]);
    let step = [4, 3, 5];
    let ldims: [usize; 3] = std::array::from_fn(|a| (grid.dims[a] - 1).div_ceil(step[a]) + 1);
    let nodes = ldims.iter().product::<usize>();
    let lattice: Vec<f32> = (0..3 * nodes)
        .map(|k| ((k * 37) % 23) as f32 * 0.1 - 1.0)
        .collect();
    let v: Vec<f32> = (0..3 * grid.len())
        .map(|k| ((k * 11) % 19) as f32 * 0.05 - 0.4)
        .collect();
    let params = RbfGradParams::new(&grid, ldims, step);
    let d = grid.dims;
    let taps = LatticeTaps::new(&params);
    let mut lhs = 0.0f64;
    for n in 0..grid.len() {
        let voxel = [n % d[0], (n / d[0]) % d[1], n / (d[0] * d[1])].map(|c| c as u32);
        let r = warp_at(&params, &lattice, &taps, voxel);
        for c in 0..3 {
            lhs += r[c] as f64 * v[3 * n + c] as f64;
        }
    }
    let splat = CpuBackend
        .lattice_splat(
            &posereg::abi::SplatParams::new(ldims, step, grid.dims),
            &Arc::new(v.clone()),
        )
        .unwrap();
    let rhs: f64 = splat
        .iter()
        .zip(&lattice)
        .map(|(a, b)| *a as f64 * *b as f64)
        .sum();
    assert!(
        (lhs - rhs).abs() < 1e-3 * lhs.abs().max(1.0),
        "{lhs} vs {rhs}"
    );
}

#[test]
fn rbf_cost_gradient_matches_finite_differences() {
    // E(f) = mean c (I0(x + R_f(x)) − T(x))² through the lattice, plus the membrane and bending
    // energies of the lattice warp; the analytic gradient (the evaluation kernels: warp_cost,
    // lattice_splat, lattice_energy, rbf_adjoint, sum_partials; then the system) against
    // central differences in one control value at a time.
    use nalgebra::Vector3;
    use posereg::abi::{
        lattice_geometry, spline_buffer, RbfGradParams, RbfLatticeParams, SplatParams,
    };
    use posereg::backend::CostImages;
    use posereg::nonrigid::rbf::RbfSystem;
    let b = CpuBackend;
    let grid = Grid::new([24, 20, 18], Affine::identity()).unwrap();
    let moving = Arc::new(smooth_volume(&grid, 41).data);
    let fixed = Arc::new(smooth_volume(&grid, 42).data);
    // A band without source data: its residuals are left out of the cost.
    let covered: Arc<Vec<f32>> =
        Arc::new((0..grid.len()).map(|n| (n % 24 > 3) as u8 as f32).collect());
    let images = CostImages {
        moving: &moving,
        fixed: &fixed,
        covered: &covered,
    };
    let centres = vec![
        Vector3::new(6.0, 5.0, 4.0),
        Vector3::new(16.0, 6.0, 9.0),
        Vector3::new(9.0, 14.0, 12.0),
        Vector3::new(18.0, 15.0, 5.0),
        Vector3::new(12.0, 9.0, 14.0),
    ];
    let positions: Vec<[f64; 3]> = centres.iter().map(|c| [c.x, c.y, c.z]).collect();
    let system = RbfSystem::new(centres.clone(), 0.0).unwrap();
    let step = [3, 2, 4];
    let ldims: [usize; 3] = std::array::from_fn(|a| (grid.dims[a] - 1).div_ceil(step[a]) + 1);
    let shape = RbfLatticeParams::new(ldims, step, centres.len());
    let geometry = Arc::new(lattice_geometry(&grid));
    let voxels = grid.len() as f64;
    let spacing = step.map(|s| s as f64);
    let energy = posereg::nonrigid::regularise::energy_params(
        ldims,
        spacing,
        40.0,
        200.0,
        (1.0 / voxels) as f32,
    );
    let evaluate = |values: &[Vector3<f64>]| {
        let coef = system.coefficients(values).unwrap();
        let spline = Arc::new(spline_buffer(&coef.affine, &positions, &coef.lambda));
        let warp = b.rbf_lattice(&shape, &geometry, &spline).unwrap();
        let (per_voxel, rows) = b
            .warp_cost(&RbfGradParams::new(&grid, ldims, step), &warp, &images)
            .unwrap();
        let splat = b
            .lattice_splat(&SplatParams::new(ldims, step, grid.dims), &per_voxel)
            .unwrap();
        let (node_gradient, terms) = b.lattice_energy(&energy, &warp, &splat).unwrap();
        let partials = b
            .rbf_adjoint(&shape, &geometry, &spline, &node_gradient)
            .unwrap();
        let adjoint = b.sum_partials(&partials, 3 * shape.rows()).unwrap();
        let total = |params, v| posereg::backend::total(&b, &params, v).unwrap();
        let cost = total(SumParams::new(rows.len()), &rows) / voxels
            + total(SumParams::new(terms.len()), &terms);
        let rows: Vec<Vector3<f64>> = adjoint
            .chunks_exact(3)
            .map(|v| Vector3::new(v[0], v[1], v[2]))
            .collect();
        let q = std::array::from_fn(|k| rows[centres.len() + k]);
        let gradient = system.value_gradient(&rows[..centres.len()], &q).unwrap();
        (cost, gradient)
    };
    // Small displacements: no voxel's sample point crosses the moving image's edge, where the
    // cost jumps (outside samples read as background) and a finite difference would measure
    // the jump instead of the slope.
    let values: Vec<Vector3<f64>> = (0..5)
        .map(|i| Vector3::new(0.03 * i as f64, -0.02, 0.01 * i as f64))
        .collect();
    let (_, analytic) = evaluate(&values);
    for (i, c) in [(1usize, 0usize), (2, 1), (4, 2), (0, 1)] {
        let eps = 1e-3;
        let mut plus = values.clone();
        plus[i][c] += eps;
        let mut minus = values.clone();
        minus[i][c] -= eps;
        let fd = (evaluate(&plus).0 - evaluate(&minus).0) / (2.0 * eps);
        // Trilinear sampling makes the cost piecewise smooth: a few percent is the
        // finite-difference noise of crossing voxel boundaries.
        assert!(
            (fd - analytic[i][c]).abs() <= 0.05 * fd.abs().max(1e-3),
            "value {i}.{c}: fd {fd} vs analytic {}",
            analytic[i][c]
        );
    }
}

#[test]
fn lncc_cost_gradient_matches_finite_differences() {
    // The LNCC image term K Σ_w c_w (1 − ρ_w²) through a lattice warp, and its gradient at the
    // lattice nodes (similarity::LnccCost, then lattice_splat) against central differences in
    // one node's displacement at a time: the gradient is exact, every window that holds a
    // voxel included, not the common approximation from the voxel's own window only.
    use posereg::abi::{RbfGradParams, SplatParams};
    use posereg::backend::CostImages;
    use posereg::images::similarity::LnccCost;
    let b = CpuBackend;
    let grid = Grid::new([20, 18, 16], Affine::identity()).unwrap();
    let moving = Arc::new(smooth_volume(&grid, 43).data);
    // The target: another texture mixed in, brightened and offset, so ρ² is well below 1.
    let other = smooth_volume(&grid, 44).data;
    let fixed: Arc<Vec<f32>> = Arc::new(
        moving
            .iter()
            .zip(&other)
            .map(|(m, o)| 1.7 * m + 0.8 * o + 30.0)
            .collect(),
    );
    let covered: Arc<Vec<f32>> =
        Arc::new((0..grid.len()).map(|n| (n % 20 > 2) as u8 as f32).collect());
    let images = CostImages {
        moving: &moving,
        fixed: &fixed,
        covered: &covered,
    };
    let step = [3; 3];
    let ldims: [usize; 3] = std::array::from_fn(|a| (grid.dims[a] - 1).div_ceil(step[a]) + 1);
    let params = RbfGradParams::new(&grid, ldims, step);
    let cost = LnccCost::new(&grid, 2, 50.0);
    let evaluate = |lattice: &[f32]| {
        let lattice = Arc::new(lattice.to_vec());
        let (per_voxel, rows) = cost.evaluate(&b, &params, &lattice, &images).unwrap();
        let splat = b
            .lattice_splat(&SplatParams::new(ldims, step, grid.dims), &per_voxel)
            .unwrap();
        (rows.iter().map(|&r| r as f64).sum::<f64>(), splat)
    };
    let nodes = ldims.iter().product::<usize>();
    let lattice: Vec<f32> = (0..3 * nodes)
        .map(|k| ((k * 37) % 23) as f32 * 0.02 - 0.2)
        .collect();
    let (_, analytic) = evaluate(&lattice);
    // Nodes inside: at the grid's faces a sample point leaves the image, where the cost
    // jumps. Node 137 is beside the uncovered band, whose voxels count through the covered
    // windows they lie in.
    for k in [3 * 137, 3 * 139 + 1, 3 * 188 + 2, 3 * 202, 3 * 141 + 1] {
        let eps = 0.05;
        let mut plus = lattice.clone();
        plus[k] += eps;
        let mut minus = lattice.clone();
        minus[k] -= eps;
        let fd = (evaluate(&plus).0 - evaluate(&minus).0) / (2.0 * eps as f64);
        let a = analytic[k] as f64;
        assert!(
            (fd - a).abs() <= 0.02 * fd.abs().max(1e-2),
            "lattice value {k}: fd {fd} vs analytic {a}"
        );
        assert!(
            fd.abs() > 1e-2,
            "lattice value {k}: a slope too small to test ({fd})"
        );
    }
}

#[test]
fn lattice_interpolation_error_of_a_cubic_rbf_warp_is_small() {
    // The warp is evaluated every 5 mm and interpolated: measure the error against evaluating
    // it at every voxel, for a warp of a few mm over a 1.25 mm grid.
    use nalgebra::Vector3;
    use posereg::nonrigid::adaptive::{Adaptive, ControlPoint};
    use posereg::nonrigid::rbf::RbfSystem;
    let mut a = Affine::identity();
    for k in 0..3 {
        a[(k, k)] = 1.25;
    }
    let grid = Grid::new([60, 56, 48], a).unwrap();
    let points: Vec<ControlPoint> = (0..20)
        .map(|i| ControlPoint {
            position: [
                (i * 13 % 60) as f64 * 1.2 + 3.0,
                (i * 7 % 56) as f64 * 1.2 + 2.0,
                (i * 5 % 48) as f64 * 1.2 + 1.0,
            ],
            displacement: [
                ((i % 5) as f64 - 2.0),
                ((i % 3) as f64 - 1.0) * 1.5,
                ((i % 4) as f64 - 1.5),
            ],
            pinned: false,
            cells: 4,
        })
        .collect();
    let centres: Vec<Vector3<f64>> = points.iter().map(|p| Vector3::from(p.position)).collect();
    let values: Vec<Vector3<f64>> = points
        .iter()
        .map(|p| Vector3::from(p.displacement))
        .collect();
    let coefficients = RbfSystem::new(centres.clone(), 0.0)
        .unwrap()
        .coefficients(&values)
        .unwrap();
    let adaptive = Adaptive {
        points,
        coefficients: coefficients.clone(),
        lattice: (grid.clone(), [4; 3]),
        stages: Vec::new(),
        evaluations: Default::default(),
    };
    let field = adaptive
        .warp_field(&CpuBackend, 1.0)
        .unwrap()
        .download_field(&CpuBackend)
        .unwrap();
    let (mut worst, mut sum) = (0.0f64, 0.0f64);
    for n in 0..grid.len() {
        let w = grid.world_of(n);
        let exact = coefficients.eval(&centres, &Vector3::new(w[0], w[1], w[2]));
        let got = field.data[n];
        let e = (0..3)
            .map(|c| (got[c] as f64 - exact[c]).powi(2))
            .sum::<f64>()
            .sqrt();
        worst = worst.max(e);
        sum += e;
    }
    let mean = sum / grid.len() as f64;
    eprintln!("lattice interpolation error: mean {mean:.4} mm, worst {worst:.4} mm");
    assert!(mean < 0.05 && worst < 0.5, "mean {mean} worst {worst}");
}

/// The lattice_energy kernel's energy and gradient (CPU twin) for one energy alone: `values`
/// (3 per node) on a lattice of `dims` nodes `spacing` mm apart; `membrane` picks the
/// membrane, else bending.
fn lattice_energy(
    values: &[f32],
    dims: [usize; 3],
    spacing: [f64; 3],
    membrane: bool,
) -> (f64, Vec<f32>) {
    let (m, b) = if membrane { (1.0, 0.0) } else { (0.0, 1.0) };
    let params = posereg::nonrigid::regularise::energy_params(dims, spacing, m, b, 0.0);
    let zero = vec![0.0f32; values.len()];
    let (gradient, terms) = CpuBackend
        .lattice_energy(&params, &Arc::new(values.to_vec()), &Arc::new(zero))
        .unwrap();
    (terms.iter().map(|&e| e as f64).sum(), gradient.to_vec())
}

const ENERGY_DIMS: [usize; 3] = [4, 5, 3];
const ENERGY_SPACING: [f64; 3] = [2.0, 3.0, 5.0];

fn energy_lattice(f: impl Fn([f64; 3]) -> [f64; 3]) -> Vec<f32> {
    let d = ENERGY_DIMS;
    (0..d.iter().product::<usize>())
        .flat_map(|n| {
            let ijk = [n % d[0], (n / d[0]) % d[1], n / (d[0] * d[1])];
            f(std::array::from_fn(|a| ijk[a] as f64 * ENERGY_SPACING[a])).map(|v| v as f32)
        })
        .collect()
}

#[test]
fn membrane_costs_nothing_for_a_translation_and_a_uniform_stretch_its_square() {
    let (d, h) = (ENERGY_DIMS, ENERGY_SPACING);
    let shift = energy_lattice(|_| [3.0, -1.0, 7.0]);
    assert_eq!(lattice_energy(&shift, d, h, true).0, 0.0);
    // R = (0.1 x, 0, 0): only the x edges differ, each by 0.1 per mm.
    let stretch = energy_lattice(|p| [0.1 * p[0], 0.0, 0.0]);
    let x_edges = (d[0] - 1) * d[1] * d[2];
    let all_edges = x_edges + d[0] * (d[1] - 1) * d[2] + d[0] * d[1] * (d[2] - 1);
    let expected = 0.01 * x_edges as f64 / all_edges as f64;
    let got = lattice_energy(&stretch, d, h, true).0;
    assert!(
        (got - expected).abs() < 1e-6 * expected,
        "{got} vs {expected}"
    );
}

#[test]
fn bending_costs_nothing_for_an_affine_warp_and_a_quadratic_its_second_derivative() {
    let (d, h) = (ENERGY_DIMS, ENERGY_SPACING);
    let affine = energy_lattice(|p| {
        [
            0.3 * p[0] - 0.2 * p[1] + 4.0,
            0.1 * p[2],
            p[0] + p[1] + p[2],
        ]
    });
    assert!(lattice_energy(&affine, d, h, false).0.abs() < 1e-9);
    // Placements: the second difference along a needs 3 nodes on axis a; the mixed one along
    // a and b needs 3 on each.
    let placements = |axes: &[usize]| -> usize {
        (0..3)
            .map(|a| if axes.contains(&a) { d[a] - 2 } else { d[a] })
            .product()
    };
    let total: usize = [&[0][..], &[1], &[2], &[0, 1], &[0, 2], &[1, 2]]
        .iter()
        .map(|axes| placements(axes))
        .sum();
    // R = (0.05 x², 0, 0): ∂²R/∂x² = 0.1 wherever the x operator lands, nothing else.
    let along_x = energy_lattice(|p| [0.05 * p[0] * p[0], 0.0, 0.0]);
    let expected = 0.01 * placements(&[0]) as f64 / total as f64;
    let got = lattice_energy(&along_x, d, h, false).0;
    assert!(
        (got - expected).abs() < 1e-5 * expected,
        "{got} vs {expected}"
    );
    // R = (0, 0.2 x z, 0): ∂²R/∂x∂z = 0.2, counted twice.
    let twisted = energy_lattice(|p| [0.0, 0.2 * p[0] * p[2], 0.0]);
    let expected = 2.0 * 0.04 * placements(&[0, 2]) as f64 / total as f64;
    let got = lattice_energy(&twisted, d, h, false).0;
    assert!(
        (got - expected).abs() < 1e-5 * expected,
        "{got} vs {expected}"
    );
}

#[test]
fn lattice_energy_gradient_matches_finite_differences() {
    let (d, h) = (ENERGY_DIMS, ENERGY_SPACING);
    let values = energy_lattice(|p| {
        [
            (0.3 * p[0]).sin() + 0.1 * p[2],
            (0.2 * p[1] * p[2]).cos(),
            0.05 * p[0] * p[1],
        ]
    });
    for membrane in [true, false] {
        let (_, gradient) = lattice_energy(&values, d, h, membrane);
        // The energy is quadratic, so a central difference is exact up to f32 rounding.
        let step = 1e-2f32;
        for n in [0, 7, 23, 31, values.len() / 3 - 1] {
            for c in 0..3 {
                let (mut plus, mut minus) = (values.clone(), values.clone());
                plus[3 * n + c] += step;
                minus[3 * n + c] -= step;
                let numeric = (lattice_energy(&plus, d, h, membrane).0
                    - lattice_energy(&minus, d, h, membrane).0)
                    / (2.0 * step as f64);
                let analytic = gradient[3 * n + c] as f64;
                assert!(
                    (numeric - analytic).abs() < 1e-3 * analytic.abs().max(1e-2),
                    "membrane {membrane}, node {n} component {c}: {numeric} vs {analytic}"
                );
            }
        }
    }
}

#[test]
fn rbf_lattice_is_the_host_evaluation_rounded_once() {
    // The kernel sums the cubic RBF in f64 in the host's order and rounds once to f32.
    use nalgebra::Vector3;
    use posereg::abi::{lattice_geometry, spline_buffer, RbfLatticeParams};
    let grid = oblique_grid([23, 19, 14]);
    let centres: Vec<Vector3<f64>> = (0..17)
        .map(|i| {
            Vector3::from(grid.voxel_to_world([
                (i * 7 % 23) as f64,
                (i * 5 % 19) as f64,
                (i % 14) as f64,
            ]))
        })
        .collect();
    let values: Vec<Vector3<f64>> = centres
        .iter()
        .map(|c| Vector3::new((0.1 * c.x).sin(), 0.3, -(0.05 * c.z).cos()))
        .collect();
    let coef = posereg::nonrigid::rbf::RbfSystem::new(centres.clone(), 0.0)
        .unwrap()
        .coefficients(&values)
        .unwrap();
    let step = [3, 2, 4];
    let ldims: [usize; 3] = std::array::from_fn(|a| (grid.dims[a] - 1).div_ceil(step[a]) + 1);
    let positions: Vec<[f64; 3]> = centres.iter().map(|c| [c.x, c.y, c.z]).collect();
    let got = CpuBackend
        .rbf_lattice(
            &RbfLatticeParams::new(ldims, step, centres.len()),
            &Arc::new(lattice_geometry(&grid)),
            &Arc::new(spline_buffer(&coef.affine, &positions, &coef.lambda)),
        )
        .unwrap();
    let nodes: Vec<Vector3<f64>> = (0..ldims.iter().product::<usize>())
        .map(|n| {
            let ijk = [
                n % ldims[0],
                (n / ldims[0]) % ldims[1],
                n / (ldims[0] * ldims[1]),
            ];
            Vector3::from(grid.voxel_to_world(std::array::from_fn(|a| (ijk[a] * step[a]) as f64)))
        })
        .collect();
    for (n, x) in nodes.iter().enumerate() {
        let want = coef.eval(&centres, x);
        for c in 0..3 {
            let g = got[3 * n + c] as f64;
            assert!(
                (g - want[c]).abs() <= 1e-6 * want[c].abs().max(1.0),
                "node {n}: {g} vs {}",
                want[c]
            );
        }
    }
}

/// The three dilate passes against a brute-force box dilation: 1 where any marked voxel lies
/// within the margin along every axis (a box), held voxels cleared; and a margin wider than
/// the grid, which marks the whole of every line with a marked voxel.
#[test]
fn dilate_passes_make_a_box_dilation_with_held_voxels_cleared() {
    let grid = Grid::new([11, 6, 9], Affine::identity()).unwrap();
    let [nx, ny, _] = grid.dims;
    let marked = |v: usize| v % 97 == 5 || v == 3 || v == grid.len() - 1;
    let mask: Vec<f32> = (0..grid.len()).map(|v| marked(v) as u8 as f32).collect();
    let held: Vec<f32> = (0..grid.len())
        .map(|v| (v % 13 == 0) as u8 as f32)
        .collect();
    let xyz = |v: usize| [v % nx, (v / nx) % ny, v / (nx * ny)];
    let held_up = CpuBackend.upload("held", held.clone()).unwrap();
    for margin in [2, 12] {
        let mut region = CpuBackend.upload("mask", mask.clone()).unwrap();
        for pass in &posereg::abi::DilateParams::passes(&grid, margin) {
            region = CpuBackend.dilate(pass, &region, &held_up).unwrap();
        }
        let region = CpuBackend.download_one(&region).unwrap();
        let unmarked = region.iter().filter(|&&x| x == 0.0).count();
        assert!(margin > 2 || unmarked > held.iter().filter(|&&h| h > 0.0).count());
        for (v, &got) in region.iter().enumerate() {
            let c = xyz(v);
            let near = (0..grid.len())
                .filter(|&n| marked(n))
                .any(|n| (0..3).all(|a| xyz(n)[a].abs_diff(c[a]) <= margin));
            let want = near && held[v] == 0.0;
            assert_eq!(got, want as u8 as f32, "margin {margin}, voxel {v} {c:?}");
        }
    }
}

/// Values in [lo, hi) from a fixed linear congruential sequence.
fn scattered(n: usize, seed: u64, (lo, hi): (f32, f32)) -> Arc<Vec<f32>> {
    let mut state = seed;
    let values = (0..n).map(|_| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * (state >> 40) as f32 / (1u64 << 24) as f32
    });
    Arc::new(values.collect())
}

/// The grids the row-at-a-time kernels are checked on: one and two voxels thin along each axis.
fn thin_grids() -> Vec<Grid> {
    [[1, 3, 2], [2, 5, 3], [4, 1, 5], [5, 3, 1]]
        .into_iter()
        .map(|dims| Grid::new(dims, Affine::identity()).unwrap())
        .collect()
}

/// Calls `check` with each voxel's index (x fastest) and its position in a grid of `dims`.
fn each_voxel(dims: [usize; 3], mut check: impl FnMut(usize, [f32; 3])) {
    let mut v = 0;
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                check(v, [i as f32, j as f32, k as f32]);
                v += 1;
            }
        }
    }
}

#[test]
fn row_kernels_match_the_per_voxel_sampling_on_thin_grids() {
    use posereg::abi::{ComposeParams, ResampleParams};
    use posereg::sample::{affine_row, blend_corners, corner_indices, linear_row, trilinear};
    for grid in thin_grids() {
        let n = grid.len();
        let d = grid.dims.map(|n| n as u32);
        let (source, field) = (
            scattered(n, 1, (0.0, 1.0)),
            scattered(3 * n, 2, (-2.5, 2.5)),
        );
        let params = ResampleParams::new(&grid, &grid, -1.0, Interpolation::Linear);
        let warped = CpuBackend.resample(&params, &source, &field).unwrap();
        let compose = ComposeParams::new(&grid, &grid);
        // The initial field is the warp itself, as in the scaling and squaring.
        let composed = CpuBackend.compose(&compose, &field, &field).unwrap();
        each_voxel(grid.dims, |v, p| {
            let u = [field[3 * v], field[3 * v + 1], field[3 * v + 2]];
            let q = posereg::sample::source_index(&params, p, u);
            assert_eq!(
                warped[v],
                trilinear(&source, q, d, -1.0),
                "resample at {p:?}"
            );
            let qc: [f32; 3] = std::array::from_fn(|a| {
                let q = affine_row(compose.index_to_initial[a], p)
                    + linear_row(compose.mm_to_initial[a], u);
                q.clamp(0.0, d[a] as f32 - 1.0)
            });
            let (corners, t) = corner_indices(qc, d);
            for c in 0..3 {
                let values = corners.map(|at| field[3 * at as usize + c]);
                let expected = u[c] + blend_corners(values, t)[0];
                assert_eq!(composed[3 * v + c], expected, "compose at {p:?}");
            }
        });
    }
}

#[test]
fn box_sums_and_the_dense_force_match_closed_forms_on_thin_grids() {
    use posereg::abi::dense::{ForceParams, ForceTerm};
    use posereg::abi::LocalMomentsParams;
    use posereg::backend::dense::ForceImages;
    for grid in thin_grids() {
        let (n, dims) = (grid.len(), grid.dims);
        let (a, b) = (scattered(n, 3, (0.0, 1.0)), scattered(n, 4, (0.0, 1.0)));
        // A radius of 3 is wider than every thin axis: the windows are cut at the faces.
        let sums = box_sums(&CpuBackend, &LocalMomentsParams::passes(&grid, 3), &a, &b).unwrap();
        each_voxel(dims, |v, p| {
            let mut expected = [0.0f64; 5];
            each_voxel(dims, |w, q| {
                if (0..3).all(|x| (p[x] - q[x]).abs() <= 3.0) {
                    let (a, b) = (a[w] as f64, b[w] as f64);
                    for (e, m) in expected.iter_mut().zip([a, b, a * a, b * b, a * b]) {
                        *e += m;
                    }
                }
            });
            for (m, e) in expected.iter().enumerate() {
                let got = sums[5 * v + m] as f64;
                assert!(
                    (got - e).abs() <= 1e-4 * e.max(1.0),
                    "moment {m} at {p:?}: {got} vs {e}"
                );
            }
        });
        // SSD with F = W + 1 on a linear ramp W: the force is W's exact gradient (0 along an
        // axis one voxel long).
        let ramp = ramp(&grid);
        let moving = Arc::new(ramp.data.clone());
        let fixed = Arc::new(ramp.data.iter().map(|w| w + 1.0).collect::<Vec<_>>());
        let covered = Arc::new(vec![1.0f32; n]);
        let images = ForceImages {
            moving: &moving,
            fixed: &fixed,
            covered: &covered,
            sums: &moving,
        };
        let params = ForceParams::new(&grid, ForceTerm::Ssd, 0);
        let (force, _) = CpuBackend.dense_force(&params, &images).unwrap();
        let slope = |a: usize, s: f32| if dims[a] > 1 { s } else { 0.0 };
        let gradient = [slope(0, 0.5), slope(1, 0.25), slope(2, 2.0)];
        for v in 0..n {
            assert_eq!(force[3 * v..3 * v + 3], gradient, "force at voxel {v}");
        }
    }
}

/// A target on every other voxel of the moving image's grid (adaptive.finest_stride) is
/// measured as the full grid is at those voxels: warp_image and warp_cost at sampled voxel a
/// give, to the bit, what they give at voxel 2a of the full grid with a lattice twice as many
/// voxels apart there (the same nodes in the world), at odd and even sizes.
#[test]
fn a_strided_target_is_measured_as_the_full_grid_is_at_its_voxels() {
    use posereg::abi::RbfGradParams;
    use posereg::backend::CostImages;
    let b = CpuBackend;
    let full = oblique_grid([21, 18, 15]);
    let sampled = full.every(2);
    assert_eq!(sampled.dims, [11, 9, 8]);
    let moving = Arc::new(smooth_volume(&full, 5).data);
    let fixed_full = smooth_volume(&full, 6).data;
    let on_sampled = |values: &[f32]| -> Vec<f32> {
        let [sx, sy, sz] = sampled.dims;
        (0..sz)
            .flat_map(|k| (0..sy).flat_map(move |j| (0..sx).map(move |i| (i, j, k))))
            .map(|(i, j, k)| values[full.index(2 * i, 2 * j, 2 * k)])
            .collect()
    };
    let step = [2, 3, 2];
    let ldims: [usize; 3] = std::array::from_fn(|a| (sampled.dims[a] - 1).div_ceil(step[a]) + 1);
    let full_step = step.map(|s| 2 * s);
    let full_ldims: [usize; 3] =
        std::array::from_fn(|a| (full.dims[a] - 1).div_ceil(full_step[a]) + 1);
    assert_eq!(ldims, full_ldims);
    let lattice: Arc<Vec<f32>> = Arc::new(
        (0..3 * ldims.iter().product::<usize>())
            .map(|k| ((k * 37) % 23) as f32 * 0.4 - 4.0)
            .collect(),
    );
    let strided = RbfGradParams::sampling(&full, 2, ldims, step);
    let whole = RbfGradParams::new(&full, full_ldims, full_step);
    let warped = |params: &RbfGradParams| b.warp_image(params, &lattice, &moving).unwrap();
    assert_eq!(*warped(&strided), on_sampled(&warped(&whole)));

    let fixed_sampled = Arc::new(on_sampled(&fixed_full));
    let (covered_sampled, covered_full) = (
        Arc::new(vec![1.0f32; sampled.len()]),
        Arc::new(vec![1.0f32; full.len()]),
    );
    let fixed_full = Arc::new(fixed_full);
    let cost = |params, fixed, covered| {
        let images = CostImages {
            moving: &moving,
            fixed,
            covered,
        };
        b.warp_cost(params, &lattice, &images).unwrap().0
    };
    let got = cost(&strided, &fixed_sampled, &covered_sampled);
    let want = cost(&whole, &fixed_full, &covered_full);
    let per_voxel =
        |g: &[f32], c: usize| -> Vec<f32> { g.iter().skip(c).step_by(3).copied().collect() };
    for c in 0..3 {
        assert_eq!(
            per_voxel(&got, c),
            on_sampled(&per_voxel(&want, c)),
            "component {c}"
        );
    }
}
