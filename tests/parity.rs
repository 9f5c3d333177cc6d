//! GPU (wgpu; lavapipe in CI) against the CPU twins, on seeded data at odd sizes.
//!
//! Tolerances: the twins run the same f32 operations in the same order, and on lavapipe the
//! results were bit-identical. A hardware driver may fuse a multiply and an add into one FMA
//! (SPIR-V allows contraction), which moves a sample coordinate by about one ulp (≈1e-5 voxel
//! at index 100); with these volumes' gradients (< 10 per voxel) that changes a sample by less
//! than 1e-3 on values of about 100. So resampling is held to 1e-3 absolute (1e-5 relative),
//! and per-cell SSD, a sum of ≈1e3 such squares folded in f64, to 1e-4 relative.

mod common;

use common::*;
use posereg::abi::Interpolation;
use posereg::cpu::CpuBackend;
use posereg::volume::{Field, Grid, Volume};
use posereg::Backend;

const RESAMPLE_TOLERANCE: f32 = 1e-3;
const SSD_RELATIVE_TOLERANCE: f64 = 1e-4;

fn check_resample(name: &str, source: &Volume, field: &Field, background: f32) {
    let Some(gpu) = gpu() else { return };
    let cpu = CpuBackend
        .resample(source, field, background, Interpolation::Linear)
        .unwrap();
    let got = gpu
        .resample(source, field, background, Interpolation::Linear)
        .unwrap();
    assert_eq!(got.grid, cpu.grid);
    let diff = max_abs_diff(&got.data, &cpu.data);
    let identical = got
        .data
        .iter()
        .zip(&cpu.data)
        .filter(|(a, b)| a == b)
        .count();
    eprintln!(
        "{name}: max |gpu - cpu| = {diff:e}, {identical}/{} bit-identical",
        cpu.data.len()
    );
    assert!(diff <= RESAMPLE_TOLERANCE, "{name}: max diff {diff}");
}

#[test]
fn resample_identity_field_at_odd_size() {
    let grid = oblique_grid([13, 11, 7]);
    let source = smooth_volume(&grid, 1);
    check_resample("identity", &source, &constant_field(&grid, [0.0; 3]), 0.0);
    // And the identity really reproduces the source on both backends.
    let gpu_out = gpu().map(|g| {
        g.resample(
            &source,
            &constant_field(&grid, [0.0; 3]),
            0.0,
            Interpolation::Linear,
        )
        .unwrap()
    });
    if let Some(out) = gpu_out {
        assert_eq!(out.data, source.data);
    }
}

#[test]
fn resample_integer_shift() {
    let grid = Grid::new([17, 9, 6], posereg::Affine::identity()).unwrap();
    let source = smooth_volume(&grid, 2);
    check_resample(
        "integer shift",
        &source,
        &constant_field(&grid, [3.0, -2.0, 1.0]),
        -5.0,
    );
}

#[test]
fn resample_fully_outside() {
    let grid = oblique_grid([9, 7, 5]);
    let source = smooth_volume(&grid, 3);
    let field = constant_field(&grid, [0.0, 1e4, 0.0]);
    check_resample("outside", &source, &field, 13.0);
    if let Some(g) = gpu() {
        assert!(g
            .resample(&source, &field, 13.0, Interpolation::Linear)
            .unwrap()
            .data
            .iter()
            .all(|&v| v == 13.0));
    }
}

#[test]
fn resample_random_smooth_field_between_different_grids() {
    let source_grid = oblique_grid([37, 29, 19]);
    let target_grid = Grid::new([31, 23, 17], {
        let mut a = posereg::Affine::identity();
        a[(0, 0)] = 1.2;
        a[(1, 1)] = 1.1;
        a[(2, 2)] = 1.3;
        a[(0, 3)] = -18.0;
        a[(1, 3)] = 5.0;
        a[(2, 3)] = 2.0;
        a
    })
    .unwrap();
    let source = smooth_volume(&source_grid, 4);
    let field = smooth_field(&target_grid, 5, 4.0);
    check_resample("random smooth", &source, &field, 0.0);
}

#[test]
fn ssd_cells_parity_at_odd_sizes() {
    let Some(gpu) = gpu() else { return };
    for (dims, cells) in [
        ([13usize, 11, 7], [2usize, 2, 2]),
        ([37, 29, 19], [4, 3, 5]),
        ([70, 65, 33], [16, 16, 16]),
    ] {
        let grid = oblique_grid(dims);
        let a = smooth_volume(&grid, 6);
        let b = smooth_volume(&grid, 7);
        let cpu = CpuBackend.ssd_cells(&a, &b, cells).unwrap();
        let got = gpu.ssd_cells(&a, &b, cells).unwrap();
        assert_eq!(got.count, cpu.count);
        for (g, c) in got.sum.iter().zip(&cpu.sum) {
            assert!(
                (g - c).abs() <= SSD_RELATIVE_TOLERANCE * c.max(1.0),
                "{dims:?}: {g} vs {c}"
            );
        }
    }
}

#[test]
fn slabs_do_not_change_results() {
    let Some(gpu) = gpu() else { return };
    let source_grid = oblique_grid([21, 19, 23]);
    let target_grid = oblique_grid([19, 17, 15]);
    let source = smooth_volume(&source_grid, 8);
    let target = smooth_volume(&target_grid, 9);
    let field = smooth_field(&target_grid, 10, 3.0);
    let whole = gpu
        .resample(&source, &field, 0.0, Interpolation::Linear)
        .unwrap();
    let whole_ssd = gpu.ssd_cells(&whole, &target, [3, 4, 5]).unwrap();
    // A second backend on its own device, forced to two slices (or fewer voxels) per dispatch.
    let small = posereg::gpu::GpuBackend::new()
        .unwrap()
        .with_max_slab_voxels(2 * 19 * 17);
    let slabs = small.plan_slabs(target_grid.dims, 12, 0).unwrap();
    assert_eq!(slabs.len(), 8, "15 slices in slabs of 2");
    let sliced = small
        .resample(&source, &field, 0.0, Interpolation::Linear)
        .unwrap();
    assert_eq!(
        sliced.data, whole.data,
        "slabs changed the resampled values"
    );
    let sliced_ssd = small.ssd_cells(&sliced, &target, [3, 4, 5]).unwrap();
    assert_eq!(sliced_ssd, whole_ssd, "slabs changed the per-cell SSD");
    // The Jacobian reads one slice either side: slabs carry a halo.
    let whole_det = gpu.jacobian(&field).unwrap();
    let sliced_det = small.jacobian(&field).unwrap();
    assert_eq!(
        sliced_det.data, whole_det.data,
        "slabs changed the Jacobian"
    );
}

#[test]
fn source_beyond_the_binding_limit_is_a_clear_error() {
    let Some(gpu) = gpu() else { return };
    let limit = gpu.context().limits.max_storage_buffer_binding_size;
    let err = gpu
        .context()
        .check_storage("source volume", limit + 4)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("source volume") && err.contains(&limit.to_string()),
        "{err}"
    );
}

#[test]
fn same_inputs_give_bit_identical_outputs() {
    let Some(gpu) = gpu() else { return };
    let grid = oblique_grid([23, 17, 11]);
    let source = smooth_volume(&grid, 12);
    let field = smooth_field(&grid, 13, 2.0);
    let a = gpu
        .resample(&source, &field, 0.0, Interpolation::Linear)
        .unwrap();
    let b = gpu
        .resample(&source, &field, 0.0, Interpolation::Linear)
        .unwrap();
    assert_eq!(a.data, b.data);
    let c = CpuBackend
        .resample(&source, &field, 0.0, Interpolation::Linear)
        .unwrap();
    let d = CpuBackend
        .resample(&source, &field, 0.0, Interpolation::Linear)
        .unwrap();
    assert_eq!(c.data, d.data);
    let s1 = gpu.ssd_cells(&a, &source, [4, 4, 4]).unwrap();
    let s2 = gpu.ssd_cells(&b, &source, [4, 4, 4]).unwrap();
    assert_eq!(s1, s2);
}

#[test]
fn jacobian_parity_at_odd_sizes() {
    let Some(gpu) = gpu() else { return };
    for dims in [[13usize, 11, 7], [30, 21, 17], [5, 1, 3]] {
        let grid = oblique_grid(dims);
        let field = smooth_field(&grid, 14, 6.0);
        let cpu = CpuBackend.jacobian(&field).unwrap();
        let got = gpu.jacobian(&field).unwrap();
        // Determinants near 1 from differences of mm-sized values: a fused multiply-add moves
        // them by a few ulp of the entries, far below 1e-4.
        let diff = max_abs_diff(&got.data, &cpu.data);
        assert!(diff <= 1e-4, "{dims:?}: max diff {diff}");
    }
}
