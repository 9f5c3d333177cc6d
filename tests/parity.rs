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
use posereg::abi::{
    pack_candidates, Blending, BoneBlend, BoneLookupParams, ComposeParams, DilateParams,
    FadeParams, Interpolation, InvertParams, JacobianParams, LabelParams, LnccParams,
    LocalMomentsParams, MomentsParams, RbfGradParams, ResampleParams, RigidParams, ScoreParams,
    ThresholdParams, FOLD_STATS_WIDTH, RIGID_SUMS, SCORE_SUMS,
};
use posereg::backend::prelude::*;
use posereg::backend::{box_sums, BoneImages};
use posereg::cpu::CpuBackend;
use posereg::volume::{Field, Grid, Image, Volume};
use posereg::Affine;

const RESAMPLE_TOLERANCE: f32 = 1e-3;
const SSD_RELATIVE_TOLERANCE: f64 = 1e-4;

fn check_resample(name: &str, source: &Volume, field: &Field, background: f32) {
    let Some(gpu) = gpu() else { return };
    let cpu = resample_volume(
        &CpuBackend,
        source,
        field,
        background,
        Interpolation::Linear,
    )
    .unwrap();
    let got = resample_volume(gpu, source, field, background, Interpolation::Linear).unwrap();
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
        resample_volume(
            g,
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
        assert!(
            resample_volume(g, &source, &field, 13.0, Interpolation::Linear)
                .unwrap()
                .data
                .iter()
                .all(|&v| v == 13.0)
        );
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

/// Coverage 1, 0.9995, 0.5 and 0 in turn: half the voxels count.
fn patchy_coverage(voxels: usize) -> Vec<f32> {
    (0..voxels)
        .map(|n| [1.0, 0.9995, 0.5, 0.0][n % 4])
        .collect()
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
        let covered = patchy_coverage(grid.len());
        let cpu = cell_ssd(&CpuBackend, (&a, &b, &covered), cells);
        let got = cell_ssd(gpu, (&a, &b, &covered), cells);
        let full = cell_ssd(&CpuBackend, (&a, &b, &vec![1.0; grid.len()]), cells);
        assert!(
            cpu.total() < 0.7 * full.total() && cpu.total() > 0.3 * full.total(),
            "{dims:?}: uncovered voxels are left out"
        );
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
    let a = resample_volume(gpu, &source, &field, 0.0, Interpolation::Linear).unwrap();
    let b = resample_volume(gpu, &source, &field, 0.0, Interpolation::Linear).unwrap();
    assert_eq!(a.data, b.data);
    let c = resample_volume(&CpuBackend, &source, &field, 0.0, Interpolation::Linear).unwrap();
    let d = resample_volume(&CpuBackend, &source, &field, 0.0, Interpolation::Linear).unwrap();
    assert_eq!(c.data, d.data);
    let covered = vec![1.0; grid.len()];
    let s1 = cell_ssd(gpu, (&a, &source, &covered), [4, 4, 4]);
    let s2 = cell_ssd(gpu, (&b, &source, &covered), [4, 4, 4]);
    assert_eq!(s1, s2);
}

#[test]
fn jacobian_parity_at_odd_sizes() {
    let Some(gpu) = gpu() else { return };
    for dims in [[13usize, 11, 7], [30, 21, 17], [5, 1, 3]] {
        let grid = oblique_grid(dims);
        let field = smooth_field(&grid, 14, 6.0);
        let cpu = host_determinant(&CpuBackend, &field).unwrap();
        let got = host_determinant(gpu, &field).unwrap();
        // Determinants near 1 from differences of mm-sized values: a fused multiply-add moves
        // them by a few ulp of the entries, far below 1e-4.
        let diff = max_abs_diff(&got, &cpu);
        assert!(diff <= 1e-4, "{dims:?}: max diff {diff}");
    }
}

/// Every element within `abs + rel × |cpu|`; prints how many are not and the worst, so that a
/// driver's failure shows its whole extent rather than the first element out of bounds.
fn close(name: &str, got: &[f32], want: &[f32], abs: f32, rel: f32) {
    close_but_a_few(name, (got, want), (abs, rel), 0);
}

/// As `close`, but up to `few` elements may miss the tolerance, each by at most 10×: for sums
/// of trilinear gradients, which jump at cell faces. A hardware driver fuses multiply-adds in a
/// sample's position (Vulkan allows it, WGSL cannot forbid it), so a sample within an ulp of a
/// face can fall in the neighbouring cell, whose gradient differs by the image's second
/// difference (measured on an NVIDIA H200: 3 of 15 979 rigid_gn partials, 1.7× the tolerance).
fn close_but_a_few(name: &str, (got, want): (&[f32], &[f32]), (abs, rel): (f32, f32), few: usize) {
    assert_eq!(got.len(), want.len(), "{name}: lengths");
    let excess = |(g, w): (&f32, &f32)| (g - w).abs() / (abs + rel * w.abs());
    let ratios: Vec<f32> = got.iter().zip(want).map(excess).collect();
    let (worst, ratio) =
        ratios.iter().enumerate().fold(
            (0, 0.0f32),
            |m, (i, &r)| if r > m.1 || r.is_nan() { (i, r) } else { m },
        );
    let beyond = ratios.iter().filter(|&&r| r.is_nan() || r > 1.0).count();
    eprintln!(
        "{name}: {beyond} of {} beyond tolerance; worst [{worst}] gpu {} vs cpu {} ({ratio:.2}× the tolerance)",
        got.len(),
        got.get(worst).unwrap_or(&0.0),
        want.get(worst).unwrap_or(&0.0)
    );
    assert!(
        beyond <= few && (beyond == 0 || ratio <= 10.0),
        "{name}: {beyond} elements beyond tolerance (at most {few} allowed, each within 10×)"
    );
}

#[test]
fn pyramid_parity_at_odd_sizes() {
    let Some(gpu) = gpu() else { return };
    for dims in [[33usize, 20, 17], [16, 40, 9]] {
        let v = smooth_volume(&oblique_grid(dims), 15);
        let cpu = one_level_down(&CpuBackend, &v);
        let got = one_level_down(gpu, &v);
        // Sums of 64 products of values ~100: a few ulp of 100 from fused multiply-adds.
        close("pyramid", &got.data, &cpu.data, 1e-3, 0.0);
    }
}

/// A source, a bone-like mask and a target moved by a known small motion.
fn rigid_case() -> (Volume, Volume, Volume, posereg::Affine) {
    let grid = oblique_grid([29, 23, 19]);
    let source = smooth_volume(&grid, 16);
    let target = smooth_volume(&grid, 16);
    let mask: Volume = posereg::Image::from_data(
        grid.clone(),
        (0..grid.len())
            .map(|n| ((n * 7919) % 5 != 0) as u8 as f32)
            .collect(),
    )
    .unwrap();
    let motion = posereg::init::rigid::small_motion(
        &nalgebra::Vector6::new(0.05, -0.03, 0.02, 1.5, -0.7, 0.4),
        &nalgebra::Vector3::new(-10.0, 20.0, 15.0),
    );
    (source, mask, target, motion)
}

/// The rigid kernels' per-column partials (Gauss-Newton sums, candidate scores) and their
/// totals added on the device.
fn rigid_outputs<B: Backend>(
    b: &B,
    (source, mask, target): (&Volume, &Volume, &Volume),
    motion: &posereg::Affine,
    candidates: &[posereg::Affine],
) -> [Vec<f64>; 4] {
    let up = |v: &Volume| b.upload("test volume", v.data.clone()).unwrap();
    let (s, m, t) = (up(source), up(mask), up(target));
    let images = BoneImages {
        source: &s,
        mask: &m,
        target: &t,
    };
    let centre = [-8.0, 18.0, 12.0];
    let params = RigidParams::new(&source.grid, &target.grid, motion, centre);
    let sums = b.rigid_sums(&params, &images).unwrap();
    let packed = b.upload("candidates", pack_candidates(candidates)).unwrap();
    let params = ScoreParams::new(&source.grid, &target.grid, candidates.len());
    let scores = b.rigid_scores(&params, &images, &packed).unwrap();
    let totals = [
        b.sum_partials(&sums, RIGID_SUMS).unwrap(),
        b.sum_partials(&scores, SCORE_SUMS * candidates.len())
            .unwrap(),
    ];
    let partials = b.download(&[&sums, &scores]).unwrap();
    let totals = b.download(&[&totals[0], &totals[1]]).unwrap();
    let wide = |v: &Vec<f32>| v.iter().map(|&x| x as f64).collect();
    [
        wide(&partials[0]),
        wide(&partials[1]),
        totals[0].clone(),
        totals[1].clone(),
    ]
}

#[test]
fn rigid_kernels_parity() {
    let Some(gpu) = gpu() else { return };
    let (source, mask, target, motion) = rigid_case();
    let candidates: Vec<posereg::Affine> = (0..7)
        .map(|k| {
            posereg::init::rigid::small_motion(
                &nalgebra::Vector6::new(0.0, 0.0, 0.02 * k as f64, k as f64, 0.0, 0.0),
                &nalgebra::Vector3::zeros(),
            ) * motion
        })
        .collect();
    let images = (&source, &mask, &target);
    let cpu = rigid_outputs(&CpuBackend, images, &motion, &candidates);
    let got = rigid_outputs(gpu, images, &motion, &candidates);
    // Column sums of up to 23 products of gradients (~10) and lever arms (~30 mm); a few may
    // hold a sample on a cell face (close_but_a_few). 0.1% of them at most.
    let narrow = |v: &[f64]| v.iter().map(|&x| x as f32).collect::<Vec<f32>>();
    let partials = (&narrow(&got[0])[..], &narrow(&cpu[0])[..]);
    close_but_a_few("rigid_gn", partials, (1e-2, 1e-4), cpu[0].len() / 1000);
    close(
        "rigid_score",
        &narrow(&got[1]),
        &narrow(&cpu[1]),
        1e-2,
        1e-4,
    );
    // The totals add the partials above: within their error times the columns' count.
    close_f64("rigid_gn totals", &got[2], &cpu[2], 1e-4);
    close_f64("rigid_score totals", &got[3], &cpu[3], 1e-4);
}

#[test]
fn sum_partials_parity_over_several_passes() {
    let Some(gpu) = gpu() else { return };
    // 2 500 chunks of 29 values: three groups of up to 1 024 chunks, then a second pass.
    let (values, chunks) = (29, 2500);
    let partials: Vec<f32> = (0..values * chunks)
        .map(|k| ((k * 7919) % 1000) as f32 * 0.37 - 150.0)
        .collect();
    let exact: Vec<f64> = (0..values)
        .map(|v| (0..chunks).map(|c| partials[c * values + v] as f64).sum())
        .collect();
    for (name, got) in [
        ("cpu", totals(&CpuBackend, &partials, values)),
        ("gpu", totals(gpu, &partials, values)),
    ] {
        close_f64(name, &got, &exact, 1e-12);
    }
}

#[test]
fn sums_of_squares_parity() {
    let Some(gpu) = gpu() else { return };
    let values: Vec<f32> = (0..5000)
        .map(|k| ((k * 7919) % 1000) as f32 * 0.37)
        .collect();
    let params = posereg::abi::SumParams::squares_about(values.len(), 185.0);
    let cpu = CpuBackend
        .sum_chunks(&params, &std::sync::Arc::new(values.clone()))
        .unwrap();
    let on_gpu = gpu.upload("values", values.clone()).unwrap();
    let got = gpu.sum_chunks(&params, &on_gpu).unwrap();
    let got = gpu.download_one(&got).unwrap();
    let exact: f64 = values.iter().map(|&v| (v as f64 - 185.0).powi(2)).sum();
    assert!((cpu.iter().sum::<f64>() - exact).abs() < 1e-9 * exact);
    close_f64("sum_chunks squares", &got, &cpu, 1e-12);
}

fn totals<B: Backend>(b: &B, partials: &[f32], values: usize) -> Vec<f64> {
    let up = b.upload("partials", partials.to_vec()).unwrap();
    b.download_one(&b.sum_partials(&up, values).unwrap())
        .unwrap()
}

#[test]
fn skinning_kernels_parity() {
    let Some(gpu) = gpu() else { return };
    let grid = oblique_grid([21, 17, 13]);
    let bones = 3;
    // Distances (one volume per bone): 0 within 1.5 voxels of the bone's centre, the distance
    // (mm, 1.3 per voxel) from there elsewhere, so the weights vary smoothly.
    let centres = [[4.0f32, 5.0, 3.0], [15.0, 8.0, 6.0], [9.0, 13.0, 10.0]];
    let distances: Vec<f32> = (0..grid.len() * bones)
        .map(|k| {
            let (j, n) = (k / grid.len(), k % grid.len());
            let p = [n % 21, (n / 21) % 17, n / (21 * 17)].map(|c| c as f32);
            let r = (0..3)
                .map(|a| (p[a] - centres[j][a]).powi(2))
                .sum::<f32>()
                .sqrt();
            1.3 * (r - 1.5).max(0.0)
        })
        .collect();
    let cpu = skin_weights(&CpuBackend, &distances, &grid, bones, 4).unwrap();
    let got = skin_weights(gpu, &distances, &grid, bones, 4).unwrap();
    close("skin_weights", &got, &cpu, 1e-6, 1e-5);
    let motions = [
        posereg::Affine::identity(),
        posereg::init::rigid::small_motion(
            &nalgebra::Vector6::new(0.4, 0.1, 0.0, 2.0, 0.0, 1.0),
            &nalgebra::Vector3::new(0.0, 5.0, 5.0),
        ),
        posereg::init::rigid::small_motion(
            &nalgebra::Vector6::new(0.2, 0.0, 0.1, 0.0, 1.0, 0.0),
            &nalgebra::Vector3::zeros(),
        ),
    ];
    let target = oblique_grid([15, 12, 11]);
    // Labels: runs of voxels in bone 1, 2, 3 and soft tissue (0).
    let label_grid = oblique_grid([30, 25, 20]);
    let bone_of_voxel: Vec<f32> = (0..label_grid.len())
        .map(|n| ((n / 7) % 4) as f32)
        .collect();
    for blending in [Blending::Linear, Blending::DualQuaternion] {
        let spec = BoneBlend {
            motions: motions.to_vec(),
            blending,
            iterations: 8,
        };
        let (cpu, got) = (
            skin_blend(
                &CpuBackend,
                &cpu,
                &grid,
                &bone_of_voxel,
                &label_grid,
                &target,
                &spec,
            )
            .unwrap(),
            skin_blend(
                gpu,
                &got,
                &grid,
                &bone_of_voxel,
                &label_grid,
                &target,
                &spec,
            )
            .unwrap(),
        );
        blends_agree(&format!("skin_blend {blending:?}"), &got, &cpu);
    }
}

/// Two skin_blend outputs (x, y, z and the residual per voxel; residual < 0.01 mm where the
/// inversion converged) agree. This fixture's labels alternate every 7 voxels, so the blend is
/// discontinuous and folds. Where it does not invert, eight steps of a non-converging iteration
/// amplify ulp differences (sqrt, division) into different iterates; where it folds, a point
/// has several preimages, and which one the iteration reaches follows near-ties between its
/// starting points (each bone's inverse), which a driver's fused multiply-adds can tip (NVIDIA
/// H200: 15–16 of 1142 converged voxels; lavapipe: none). So: both converge on the same voxels but
/// 1 in 100; where both did, at most 5% lie on another preimage (> 0.1 mm apart) and the rest
/// agree within ulps plus their residuals.
fn blends_agree(name: &str, got: &[f32], cpu: &[f32]) {
    let converged = |out: &[f32]| out[3] < 0.01;
    let apart = |g: &[f32], c: &[f32]| (0..3).map(|k| (g[k] - c[k]).abs()).fold(0.0, f32::max);
    let voxels: Vec<(&[f32], &[f32])> = got.chunks(4).zip(cpu.chunks(4)).collect();
    let cpu_converged = voxels.iter().filter(|(_, c)| converged(c)).count();
    let one_only = voxels
        .iter()
        .filter(|(g, c)| converged(g) != converged(c))
        .count();
    let both: Vec<_> = voxels
        .iter()
        .filter(|(g, c)| converged(g) && converged(c))
        .collect();
    let other = both.iter().filter(|(g, c)| apart(g, c) > 0.1).count();
    let worst = both
        .iter()
        .filter(|(g, c)| apart(g, c) <= 0.1)
        .map(|(g, c)| apart(g, c) / (2e-3 + 2.0 * (g[3] + c[3])))
        .fold(0.0f32, f32::max);
    eprintln!(
        "{name}: {cpu_converged} of {} voxels converged on the cpu, {one_only} on one backend \
         only, {other} of {} on another preimage; the rest {worst:.2}× their tolerance apart",
        voxels.len(),
        both.len()
    );
    assert!(cpu_converged > voxels.len() / 8 && one_only <= voxels.len() / 100);
    assert!(other <= both.len() / 20 && worst <= 1.0);
}

/// warp_image, then the gain's kernels on it (terms, a pyramid level down, ratio, applied back
/// to the moving image), each downloaded.
fn warp_and_gain<B: Backend>(
    b: &B,
    (moving, fixed): (&Volume, &Volume),
    lattice: &[f32],
    (ldims, step): ([usize; 3], [usize; 3]),
) -> [Vec<f32>; 4] {
    use posereg::abi::{GainParams, RbfGradParams};
    let grid = &fixed.grid;
    let up = |v: &[f32]| b.upload("test data", v.to_vec()).unwrap();
    let (m, f, l) = (up(&moving.data), up(&fixed.data), up(lattice));
    let warped = b
        .warp_image(&RbfGradParams::new(grid, ldims, step), &l, &m)
        .unwrap();
    let (product, energy) = b
        .gain_terms(&GainParams::new(grid, grid, 0.0, 2.0), &warped, &f)
        .unwrap();
    let (coarse, factors) = posereg::images::pyramid::next_level_grid(grid).unwrap();
    let down = posereg::abi::PyramidParams::new(grid, coarse.dims, factors);
    let (product, energy) = (
        b.pyramid_level(&down, &product).unwrap(),
        b.pyramid_level(&down, &energy).unwrap(),
    );
    // A floor that some coarse voxels fall below, so both branches run.
    let floor = 0.5 * 100.0f32.powi(2);
    let ratio = GainParams::new(&coarse, &coarse, floor, 1.2);
    let gain = b.gain_ratio(&ratio, &product, &energy).unwrap();
    let apply = GainParams::new(grid, &coarse, floor, 1.2);
    let gained = b.gain_apply(&apply, &gain, &m).unwrap();
    b.download(&[&warped, &product, &gain, &gained])
        .unwrap()
        .try_into()
        .unwrap()
}

#[test]
fn warp_image_and_gain_kernels_parity() {
    let Some(gpu) = gpu() else { return };
    let grid = oblique_grid([27, 22, 17]);
    let moving = smooth_volume(&grid, 51);
    let fixed = smooth_volume(&grid, 52);
    let step = [4, 3, 5];
    let ldims: [usize; 3] = std::array::from_fn(|a| (grid.dims[a] - 1).div_ceil(step[a]) + 1);
    let lattice: Vec<f32> = (0..3 * ldims.iter().product::<usize>())
        .map(|k| ((k * 29) % 31) as f32 * 0.2 - 3.0)
        .collect();
    let images = (&moving, &fixed);
    let cpu = warp_and_gain(&CpuBackend, images, &lattice, (ldims, step));
    let got = warp_and_gain(gpu, images, &lattice, (ldims, step));
    assert!(
        cpu[0].iter().filter(|&&w| w == 0.0).count() > 0,
        "some samples fall outside the moving image"
    );
    let (clamped, unity) = (
        cpu[2]
            .iter()
            .filter(|&&g| g == 1.2 || g == 1.0 / 1.2)
            .count(),
        cpu[2].iter().filter(|&&g| g == 1.0).count(),
    );
    assert!(clamped > 0 && unity > 0, "{clamped} clamped, {unity} at 1");
    // Values ~100 sampled at points that move by ulps between the backends.
    close("warp_image", &got[0], &cpu[0], 2e-2, 1e-4);
    close("gain_terms", &got[1], &cpu[1], 2.0, 1e-4);
    close("gain_ratio", &got[2], &cpu[2], 1e-4, 1e-4);
    close("gain_apply", &got[3], &cpu[3], 2e-2, 1e-4);
}

/// Every output of one non-rigid cost evaluation, downloaded.
struct Evaluation {
    warp: Vec<f32>,
    gradient: Vec<f32>,
    rows: Vec<f32>,
    splat: Vec<f32>,
    node_gradient: Vec<f32>,
    energy: Vec<f32>,
    adjoint: Vec<f64>,
    sums: Vec<f64>,
}

/// A warp of `points` control points with smooth values over `grid`, as the RBF kernels read it.
fn spline_over(grid: &Grid, points: usize) -> Vec<f64> {
    use nalgebra::Vector3;
    let centres: Vec<Vector3<f64>> = (0..points)
        .map(|p| {
            let f = |k: usize| ((p * 7919 + k * 104729) % 997) as f64 / 997.0;
            let ijk: [f64; 3] = std::array::from_fn(|a| f(a) * (grid.dims[a] - 1) as f64);
            Vector3::from(grid.voxel_to_world(ijk))
        })
        .collect();
    let values: Vec<Vector3<f64>> = centres
        .iter()
        .map(|c| Vector3::new((0.1 * c.x).sin(), (0.07 * c.y).cos(), 0.02 * c.z))
        .collect();
    let coef = posereg::nonrigid::rbf::RbfSystem::new(centres.clone(), 0.0)
        .unwrap()
        .coefficients(&values)
        .unwrap();
    let positions: Vec<[f64; 3]> = centres.iter().map(|c| [c.x, c.y, c.z]).collect();
    posereg::abi::spline_buffer(&coef.affine, &positions, &coef.lambda)
}

/// Runs the kernels of one evaluation on `b`, as the adaptive stage chains them: the moving
/// image (`images[0]`) on its own grid, the target and the coverage on every `stride`-th of
/// its voxels.
fn evaluate<B: Backend>(
    b: &B,
    (moving_grid, stride): (&Grid, usize),
    images: [&Volume; 3],
    step: [usize; 3],
    spline: &[f64],
) -> Evaluation {
    use posereg::abi::{lattice_geometry, RbfGradParams, RbfLatticeParams, SplatParams};
    let grid = &moving_grid.every(stride);
    let ldims: [usize; 3] = std::array::from_fn(|a| (grid.dims[a] - 1).div_ceil(step[a]) + 1);
    let points = (spline.len() - 12) / 6;
    let shape = RbfLatticeParams::new(ldims, step, points);
    let up = |what, v: &Volume| b.upload(what, v.data.clone()).unwrap();
    let (moving, fixed, covered) = (
        up("moving", images[0]),
        up("fixed", images[1]),
        up("covered", images[2]),
    );
    let geometry = b.upload("geometry", lattice_geometry(grid)).unwrap();
    let spline = b.upload("spline", spline.to_vec()).unwrap();
    let warp = b.rbf_lattice(&shape, &geometry, &spline).unwrap();
    let images = posereg::backend::CostImages {
        moving: &moving,
        fixed: &fixed,
        covered: &covered,
    };
    let params = RbfGradParams::sampling(moving_grid, stride, ldims, step);
    let (gradient, rows) = b.warp_cost(&params, &warp, &images).unwrap();
    let splat = b
        .lattice_splat(&SplatParams::new(ldims, step, grid.dims), &gradient)
        .unwrap();
    let h = grid.spacing();
    let spacing: [f64; 3] = std::array::from_fn(|a| h[a] * step[a] as f64);
    let energy_params =
        posereg::nonrigid::regularise::energy_params(ldims, spacing, 3.0, 0.5, 1e-3);
    let (node_gradient, energy) = b.lattice_energy(&energy_params, &warp, &splat).unwrap();
    let partials = b
        .rbf_adjoint(&shape, &geometry, &spline, &node_gradient)
        .unwrap();
    let adjoint = b.sum_partials(&partials, 3 * shape.rows()).unwrap();
    let sums = b
        .sum_chunks(
            &posereg::abi::SumParams::new(grid.dims[1] * grid.dims[2]),
            &rows,
        )
        .unwrap();
    let [warp, gradient, rows, splat, node_gradient, energy]: [Vec<f32>; 6] = b
        .download(&[&warp, &gradient, &rows, &splat, &node_gradient, &energy])
        .unwrap()
        .try_into()
        .unwrap();
    let [adjoint, sums]: [Vec<f64>; 2] =
        b.download(&[&adjoint, &sums]).unwrap().try_into().unwrap();
    Evaluation {
        warp,
        gradient,
        rows,
        splat,
        node_gradient,
        energy,
        adjoint,
        sums,
    }
}

/// Every element within `rel ×` the largest |cpu| value; prints the worst.
fn close_f64(name: &str, got: &[f64], want: &[f64], rel: f64) {
    assert_eq!(got.len(), want.len(), "{name}: lengths");
    let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-30);
    let (at, worst) = got
        .iter()
        .zip(want)
        .map(|(a, b)| (a - b).abs())
        .enumerate()
        .fold((0, 0.0f64), |m, (i, d)| if d > m.1 { (i, d) } else { m });
    eprintln!(
        "{name}: max |gpu - cpu| = {worst:e} at [{at}] (largest value {scale:e}; {:.2e} of it)",
        worst / scale
    );
    assert!(worst <= rel * scale, "{name}: {worst} > {rel} × {scale}");
}

#[test]
fn nonrigid_evaluation_kernels_parity() {
    let Some(gpu) = gpu() else { return };
    // A coarse lattice of odd size, its step different along each axis; every voxel a node
    // (as at coarse pyramid levels), over more than 65 535 nodes (llvmpipe ends longer loops:
    // shaders/nonrigid/rbf_adjoint.wgsl); and the target on every other voxel of the moving
    // image (adaptive.finest_stride), at odd sizes.
    let cases = [
        ([27, 22, 17], [4, 3, 5], 40, 1),
        ([41, 64, 27], [1; 3], 23, 1),
        ([27, 22, 17], [2, 3, 2], 40, 2),
    ];
    for (dims, step, points, stride) in cases {
        let moving_grid = oblique_grid(dims);
        let grid = moving_grid.every(stride);
        let moving = smooth_volume(&moving_grid, 61);
        let fixed = smooth_volume(&grid, 62);
        // Coverage: a slab of slices without source data.
        let slice = grid.dims[0] * grid.dims[1];
        let covered = posereg::Image::from_data(
            grid.clone(),
            (0..grid.len())
                .map(|n| (n / slice > 2) as u8 as f32)
                .collect(),
        )
        .unwrap();
        let spline = spline_over(&grid, points);
        let images = [&moving, &fixed, &covered];
        let sampling = (&moving_grid, stride);
        let want = evaluate(&CpuBackend, sampling, images, step, &spline);
        let got = evaluate(gpu, sampling, images, step, &spline);
        let name = |k: &str| format!("step {step:?}, stride {stride}: {k}");
        // The warp is summed in f64 and rounded once to f32: equal up to the last bit.
        close(&name("rbf_lattice"), &got.warp, &want.warp, 1e-5, 1e-6);
        // As rbf_grad: 2 r ∇I0 with r up to ~100, |∇| up to ~10.
        close(
            &name("warp_cost gradient"),
            &got.gradient,
            &want.gradient,
            2e-2,
            1e-4,
        );
        close(&name("warp_cost rows"), &got.rows, &want.rows, 1e-1, 1e-4);
        close(&name("lattice_splat"), &got.splat, &want.splat, 1e-1, 1e-4);
        close(
            &name("lattice_energy gradient"),
            &got.node_gradient,
            &want.node_gradient,
            1e-3,
            1e-4,
        );
        close(
            &name("lattice_energy terms"),
            &got.energy,
            &want.energy,
            1e-6,
            1e-4,
        );
        close_f64(&name("rbf_adjoint"), &got.adjoint, &want.adjoint, 1e-4);
        close_f64(&name("sum_chunks"), &got.sums, &want.sums, 1e-5);
    }
}

/// The warp_field kernel from a host lattice, brought back.
fn warp_field_on<B: Backend>(backend: &B, params: &RbfGradParams, lattice: &[f32]) -> Vec<f32> {
    let up = backend.upload("lattice", lattice.to_vec()).unwrap();
    backend
        .download_one(&backend.warp_field(params, &up).unwrap())
        .unwrap()
}

/// A field's values where `backend` computes.
fn field_on<B: Backend>(backend: &B, field: &Field) -> B::Buffer<f32> {
    backend
        .upload("field", bytemuck::cast_slice(&field.data).to_vec())
        .unwrap()
}

#[test]
fn final_field_kernels_parity_at_odd_sizes() {
    let Some(gpu) = gpu() else { return };
    let grid = oblique_grid([23, 18, 13]);
    // warp_field: a lattice every 4, 3 and 5 voxels along x, y and z.
    let step = [4, 3, 5];
    let ldims: [usize; 3] = std::array::from_fn(|a| (grid.dims[a] - 1).div_ceil(step[a]) + 1);
    let lattice: Vec<f32> = (0..3 * ldims.iter().product::<usize>())
        .map(|k| ((k * 29) % 31) as f32 * 0.2 - 3.0)
        .collect();
    let params = RbfGradParams::new(&grid, ldims, step);
    let want = warp_field_on(&CpuBackend, &params, &lattice);
    let got = warp_field_on(gpu, &params, &lattice);
    // Trilinear weights of mm-sized node values: ulps.
    close("warp_field", &got, &want, 1e-5, 1e-6);
    // compose: a warp of a few mm, some of it reaching beyond the grid (clamped there); the
    // initial field on the same grid, then on another (chained poses).
    let warp = smooth_field(&grid, 71, 4.0);
    let other = Grid::new([19, 21, 11], oblique_affine([1.3, 0.8, 1.9])).unwrap();
    for initial_grid in [&grid, &other] {
        let initial = smooth_field(initial_grid, 72, 10.0);
        let params = ComposeParams::new(&grid, initial_grid);
        let want = compose_on(&CpuBackend, &params, &warp, &initial);
        let got = compose_on(gpu, &params, &warp, &initial);
        // As resampling: an FMA moves a sample point by an ulp; gradients of u0 are below
        // 1 mm per voxel here.
        close("compose", &got, &want, 1e-4, 1e-5);
    }
    // fade_warp: the distance to the nearest bone, zero on the bones, up to 16 mm off them.
    let distance: Vec<f32> = (0..grid.len())
        .map(|k| ((k * 37) % 41).saturating_sub(8) as f32 * 0.5)
        .collect();
    let params = FadeParams::new(&grid, 6.0);
    let faded = |b: &dyn Fn(&Field, &[f32]) -> Vec<f32>| b(&warp, &distance);
    let want = faded(&|w, d| fade_on(&CpuBackend, &params, w, d));
    let got = faded(&|w, d| fade_on(gpu, &params, w, d));
    // One division and one product per value: an ulp or two.
    close("fade_warp", &got, &want, 1e-6, 1e-6);
}

/// The fade_warp kernel on a host warp and distance stack, brought back.
fn fade_on<B: Backend>(
    backend: &B,
    params: &FadeParams,
    warp: &Field,
    distance: &[f32],
) -> Vec<f32> {
    let r = field_on(backend, warp);
    let d = backend.upload("distance", distance.to_vec()).unwrap();
    backend
        .download_one(&backend.fade_warp(params, &r, &d).unwrap())
        .unwrap()
}

/// The compose kernel on host fields, brought back.
fn compose_on<B: Backend>(
    backend: &B,
    params: &ComposeParams,
    warp: &Field,
    initial: &Field,
) -> Vec<f32> {
    let (r, u0) = (field_on(backend, warp), field_on(backend, initial));
    backend
        .download_one(&backend.compose(params, &r, &u0).unwrap())
        .unwrap()
}

/// Composing with an initial field on another grid: u0 affine in world space (which trilinear
/// interpolation reproduces), so u(x) = r + u0(x + r) exactly where x + r lies inside u0's
/// grid.
#[test]
fn compose_reads_the_initial_field_on_its_own_grid() {
    let grid = Grid::new([12, 10, 8], oblique_affine([1.1, 0.9, 1.7])).unwrap();
    // An axis-aligned grid of 1.3 mm voxels over most of the oblique one's box.
    let corners: Vec<nalgebra::Vector3<f64>> = (0..8)
        .map(|c| {
            let ijk: [f64; 3] =
                std::array::from_fn(|a| ((c >> a) & 1) as f64 * grid.dims[a] as f64);
            grid.voxel_to_world(ijk).into()
        })
        .collect();
    let low = corners.iter().fold(corners[0], |m, c| m.inf(c));
    let high = corners.iter().fold(corners[0], |m, c| m.sup(c));
    let mut affine = Affine::new_scaling(1.3);
    affine[(3, 3)] = 1.0;
    affine
        .fixed_view_mut::<3, 1>(0, 3)
        .copy_from(&(low + nalgebra::Vector3::repeat(2.0)));
    let dims: [usize; 3] = std::array::from_fn(|a| ((high[a] - low[a]) / 1.3) as usize);
    let initial_grid = Grid::new(dims, affine).unwrap();
    let u0 = |y: nalgebra::Vector3<f64>| -> [f64; 3] {
        [
            0.02 * y[0] - 0.01 * y[2] + 1.5,
            0.03 * y[1] + 0.01 * y[0] - 2.0,
            -0.02 * y[2] + 0.5,
        ]
    };
    let initial = Image::from_data(
        initial_grid.clone(),
        (0..initial_grid.len())
            .map(|n| u0(initial_grid.world_of(n)).map(|v| v as f32))
            .collect(),
    )
    .unwrap();
    let r = [0.7f32, -1.2, 0.4];
    let warp = Image::filled(grid.clone(), r);
    let params = ComposeParams::new(&grid, &initial_grid);
    let got = compose_on(&CpuBackend, &params, &warp, &initial);
    let mut checked = 0;
    for n in 0..grid.len() {
        let y = grid.world_of(n) + nalgebra::Vector3::new(r[0], r[1], r[2]).cast::<f64>();
        let index = initial_grid.world_to_voxel_affine() * y.push(1.0);
        if (0..3).any(|a| index[a] < 0.0 || index[a] > initial_grid.dims[a] as f64 - 1.0) {
            continue;
        }
        let want = u0(y);
        for c in 0..3 {
            let expected = r[c] as f64 + want[c];
            assert!(
                (got[3 * n + c] as f64 - expected).abs() < 1e-4,
                "voxel {n} component {c}: {} against {expected}",
                got[3 * n + c]
            );
        }
        checked += 1;
    }
    assert!(checked > grid.len() / 2, "only {checked} voxels inside");
}

/// A label map of codes 0..6 in runs along x, as f32, on `grid`.
fn label_runs(grid: &Grid) -> Vec<f32> {
    (0..grid.len()).map(|n| ((n / 3) % 7) as f32).collect()
}

/// The label and coverage kernels on both backends: which label each voxel has among a list,
/// which bone each target voxel's source point lands in (within a residual limit), and where
/// the source is seen at all. Integer-valued outputs: they must agree exactly except where an
/// FMA moves a sample point across a voxel's rounding boundary, which these fixtures avoid
/// counting on by allowing a handful of voxels.
#[test]
fn label_and_coverage_kernels_parity() {
    let Some(gpu) = gpu() else { return };
    let labels_grid = oblique_grid([21, 17, 13]);
    let target = oblique_grid([19, 15, 11]);
    let labels = label_runs(&labels_grid);
    let field = smooth_field(&target, 81, 6.0);
    let residual: Vec<f32> = (0..target.len()).map(|n| (n % 10) as f32 * 0.1).collect();
    let bones = [2u16, 3, 5];
    let cpu = label_outputs(
        &CpuBackend,
        &labels_grid,
        &target,
        &labels,
        &field,
        &residual,
        &bones,
    );
    let got = label_outputs(
        gpu,
        &labels_grid,
        &target,
        &labels,
        &field,
        &residual,
        &bones,
    );
    for (name, (g, c)) in ["label_index", "bone_at_source", "coverage"]
        .iter()
        .zip(got.iter().zip(&cpu))
    {
        let differ = g.iter().zip(c).filter(|(a, b)| a != b).count();
        eprintln!("{name}: {differ} of {} voxels differ", c.len());
        assert!(differ <= c.len() / 1000, "{name}: {differ} voxels differ");
    }
    // The fixtures exercise every outcome: each code and none, bones found and not, voxels
    // seen and not.
    for code in 0..=bones.len() {
        assert!(
            cpu[0].contains(&(code as f32)),
            "label_index never gave {code}"
        );
        assert!(
            cpu[1].contains(&(code as f32)),
            "bone_at_source never gave {code}"
        );
    }
    assert!(cpu[2].contains(&0.0) && cpu[2].contains(&1.0));
}

/// label_index, bone_at_source (residual limit 0.45 mm) and coverage, brought back.
fn label_outputs<B: Backend>(
    b: &B,
    labels_grid: &Grid,
    target: &Grid,
    labels: &[f32],
    field: &Field,
    residual: &[f32],
    bones: &[u16],
) -> [Vec<f32>; 3] {
    let labels_up = b.upload("labels", labels.to_vec()).unwrap();
    let field_up = field_on(b, field);
    let residual_up = b.upload("residual", residual.to_vec()).unwrap();
    let index = b
        .label_index(&LabelParams::new(labels_grid, bones).unwrap(), &labels_up)
        .unwrap();
    let lookup = BoneLookupParams::new(labels_grid, target, bones, 0.45).unwrap();
    let bone = b
        .bone_at_source(&lookup, &field_up, &residual_up, &labels_up)
        .unwrap();
    let seen = ResampleParams::new(labels_grid, target, 0.0, Interpolation::Linear);
    // A target mask with a hole every seventh voxel.
    let mask: Vec<f32> = (0..target.len())
        .map(|n| (n % 7 != 0) as u8 as f32)
        .collect();
    let mask_up = b.upload("mask", mask).unwrap();
    let covered = b.coverage(&seen, &field_up, &mask_up).unwrap();
    let mut out = b.download(&[&index, &bone, &covered]).unwrap();
    let covered = out.pop().unwrap();
    let bone = out.pop().unwrap();
    [out.pop().unwrap(), bone, covered]
}

/// The fold repair's kernels on both backends, on a field that folds in places beside a bone:
/// the determinant's statistics per chunk, the folded voxels, the region dilated from them,
/// and one smoothing sweep over it.
#[test]
fn fold_kernels_parity() {
    let Some(gpu) = gpu() else { return };
    let grid = oblique_grid([29, 23, 19]);
    // A smooth field with large gradients: its determinant goes below zero in places.
    let field = smooth_field(&grid, 91, 9.0);
    let labels = label_runs(&grid);
    // Runs of voxels held in bone 1 or bone 2, three voxels in four: where a voxel's stencil
    // neighbours are all held, in both bones, a bone contact.
    let held: Vec<f32> = (0..grid.len())
        .map(|n| ((n / 5) % 4 != 0) as u8 as f32 * (1 + (n / 60) % 2) as f32)
        .collect();
    let cpu = fold_outputs(&CpuBackend, &grid, &field, &labels, &held);
    let got = fold_outputs(gpu, &grid, &field, &labels, &held);
    let contacts: f32 = cpu[1].chunks(FOLD_STATS_WIDTH).map(|c| c[4]).sum();
    assert!(contacts > 0.0, "the fixture has folded bone contacts");
    let det = &cpu[0];
    let folded = det.iter().filter(|&&d| d <= 0.05).count();
    assert!(
        folded > grid.len() / 50 && folded < grid.len() / 2,
        "the fixture folds in places: {folded} of {} voxels",
        grid.len()
    );
    // Determinants: ulps (see jacobian_parity_at_odd_sizes).
    close("jacobian", &got[0], &cpu[0], 1e-4, 1e-5);
    // Statistics: minima to ulps, counts exact but for voxels within an ulp of a threshold.
    close("fold_stats", &got[1], &cpu[1], 1e-4, 1e-3);
    for (name, k) in [("mark_at_most", 2), ("dilate", 3)] {
        let differ = got[k].iter().zip(&cpu[k]).filter(|(a, b)| a != b).count();
        assert!(
            differ <= grid.len() / 1000,
            "{name}: {differ} voxels differ"
        );
    }
    let region = cpu[3].iter().filter(|&&r| r > 0.0).count();
    assert!(
        region > cpu[2].iter().filter(|&&m| m > 0.0).count(),
        "the dilation grows the mask"
    );
    // Means of mm-sized displacements: ulps, except where an ulp moves a voxel's source point
    // into or out of a bone (then the mean is kept or refused): a handful of voxels.
    let off = got[4]
        .iter()
        .zip(&cpu[4])
        .filter(|(a, b)| (*a - *b).abs() > 1e-4 * (1.0 + b.abs()))
        .count();
    assert!(
        off <= 3 * grid.len() / 1000,
        "fold_smooth: {off} values differ"
    );
}

/// The distance maps (three edt passes over two regions at once, on an anisotropic oblique
/// grid) and the moments of a smoothed map, on both backends.
#[test]
fn distance_and_moments_kernels_parity() {
    let Some(gpu) = gpu() else { return };
    let grid = Grid::new([23, 19, 14], oblique_affine([1.1, 0.9, 1.7])).unwrap();
    // Regions 1 and 2 in scattered runs; the rest 0.
    let index: Vec<f32> = (0..grid.len())
        .map(|n| match n % 97 {
            0..=2 => 1.0,
            50 => 2.0,
            _ => 0.0,
        })
        .collect();
    let cpu = distances_and_moments(&CpuBackend, &grid, &index);
    let got = distances_and_moments(gpu, &grid, &index);
    // Square roots of sums of squared mm: ulps.
    close("edt", &got.0, &cpu.0, 1e-4, 1e-5);
    // Sums (f64) of voxel positions and their products; a driver that fuses multiply-adds
    // moves each f32 position by an ulp (6e-8 of it): 1.2e-8 of the largest moment measured
    // on an NVIDIA H200, none on lavapipe.
    close_f64("moments", &got.1, &cpu.1, 1e-7);
    assert!(cpu.1[0] > 0.0 && cpu.0.iter().all(|d| d.is_finite()));
}

/// The distance maps of `index`'s regions 1 and 2 followed by the distance to the nearer, and
/// the moments of region 1's distances at or above 3 mm, brought back.
fn distances_and_moments<B: Backend>(b: &B, grid: &Grid, index: &[f32]) -> (Vec<f32>, Vec<f64>) {
    let index = posereg::backend::DeviceImage::<B> {
        data: b.upload("index", index.to_vec()).unwrap(),
        grid: grid.clone(),
    };
    let maps = posereg::images::regions::distance_maps(b, &index, 2).unwrap();
    let nearest = posereg::images::regions::distance_to_nearest(b, &index).unwrap();
    let far = b.moments(&MomentsParams::new(grid, 3.0), &maps).unwrap();
    let out = b.download(&[&maps, &nearest]).unwrap();
    (out.concat(), b.download_one(&far).unwrap())
}

/// jacobian, fold_stats, mark_at_most, the three dilate passes and one fold_smooth, brought back.
fn fold_outputs<B: Backend>(
    b: &B,
    grid: &Grid,
    field: &Field,
    labels: &[f32],
    held: &[f32],
) -> [Vec<f32>; 5] {
    let field_up = field_on(b, field);
    let labels_up = b.upload("labels", labels.to_vec()).unwrap();
    let held_up = b.upload("held", held.to_vec()).unwrap();
    let det = b.jacobian(&JacobianParams::new(grid), &field_up).unwrap();
    let folds = ThresholdParams::new(grid, 0.05);
    let stats = b.fold_stats(&folds, &det, &held_up).unwrap();
    let mark = b.mark_at_most(&folds, &det, &held_up).unwrap();
    let mut region = mark.clone();
    for pass in &DilateParams::passes(grid, 2) {
        region = b.dilate(pass, &region, &held_up).unwrap();
    }
    let lookup = BoneLookupParams::new(grid, grid, &[2, 3], f32::MAX).unwrap();
    let smoothed = b
        .fold_smooth(&lookup, &field_up, &region, &labels_up)
        .unwrap();
    let mut out = b
        .download(&[&det, &stats, &mark, &region, &smoothed])
        .unwrap();
    std::array::from_fn(|_| out.remove(0))
}

/// invert_field on both backends: a smooth field of a few mm on an oblique grid, inverted onto
/// a grid that reaches beyond it (some of its voxels have no preimage). Newton's method stops
/// at 1e-4 mm, so converged answers agree to about that; whether a point has a preimage
/// agrees but for points on the field grid's edge.
#[test]
fn invert_field_parity() {
    let Some(gpu) = gpu() else { return };
    let field_grid = oblique_grid([23, 19, 13]);
    let mut out_grid = Grid::new([21, 17, 15], oblique_affine([1.2, 1.0, 1.5])).unwrap();
    out_grid.affine[(0, 3)] += 3.0;
    let field = smooth_field(&field_grid, 91, 1.5);
    let params = InvertParams::new(&field_grid, &out_grid);
    let (want, want_residual) = inverted(&CpuBackend, &params, &field);
    let (got, got_residual) = inverted(gpu, &params, &field);
    let (mut both, mut disagree) = (0usize, 0usize);
    for n in 0..out_grid.len() {
        let (c, g) = (want_residual[n], got_residual[n]);
        if (c < 0.0) != (g < 0.0) {
            disagree += 1;
        } else if (0.0..1e-3).contains(&c) && (0.0..1e-3).contains(&g) {
            both += 1;
            for a in 0..3 {
                let (x, y) = (want[3 * n + a], got[3 * n + a]);
                assert!((x - y).abs() <= 2e-3, "voxel {n}: gpu {y} vs cpu {x}");
            }
        }
    }
    let with_preimage = want_residual.iter().filter(|&&r| r >= 0.0).count();
    eprintln!("invert_field: {both} converged on both of {with_preimage} with a preimage; {disagree} disagree on having one");
    assert!(
        disagree * 100 <= out_grid.len(),
        "{disagree} voxels disagree"
    );
    assert!(
        both * 10 >= with_preimage * 9,
        "{both} of {with_preimage} converged"
    );
    assert!(
        with_preimage * 10 <= out_grid.len() * 9,
        "the fixture has no voxels without a preimage"
    );
}

/// invert_field's two outputs, brought back.
fn inverted<B: Backend>(backend: &B, params: &InvertParams, field: &Field) -> (Vec<f32>, Vec<f32>) {
    let (w, r) = backend
        .invert_field(params, &field_on(backend, field))
        .unwrap();
    (
        backend.download_one(&w).unwrap(),
        backend.download_one(&r).unwrap(),
    )
}

/// The local correlation's box sums (three local_moments passes, radius 2 at an odd size, so
/// windows are cut at every face) and the per-chunk ρ² sums, on both backends.
#[test]
fn local_correlation_kernels_parity() {
    let Some(gpu) = gpu() else { return };
    let grid = oblique_grid([19, 14, 11]);
    let (a, b) = (smooth_volume(&grid, 21), smooth_volume(&grid, 22));
    let cpu = local_correlation_outputs(&CpuBackend, &grid, &a.data, &b.data);
    let got = local_correlation_outputs(gpu, &grid, &a.data, &b.data);
    // Sums of ≤ 125 products of values ~100: a fused multiply-add moves them by ulps of 1e6.
    close("local_moments", &got.0, &cpu.0, 0.0, 1e-5);
    // ρ² from differences of those sums, in [0, 1], summed over 1024 voxels.
    close("lncc", &got.1, &cpu.1, 1e-2, 1e-4);
    assert!(cpu.1.chunks(2).all(|c| c[1] > 0.0 && c[0] > 0.0));
}

/// The box sums after the last pass and the per-chunk ρ² sums of `a` and `b`, brought back.
fn local_correlation_outputs<B: Backend>(
    backend: &B,
    grid: &Grid,
    a: &[f32],
    b: &[f32],
) -> (Vec<f32>, Vec<f32>) {
    let passes = LocalMomentsParams::passes(grid, 2);
    let (a, b) = (
        backend.upload("a", a.to_vec()).unwrap(),
        backend.upload("b", b.to_vec()).unwrap(),
    );
    let boxed = box_sums(backend, &passes, &a, &b).unwrap();
    let sums = backend.lncc(&LnccParams::new(grid, 2), &boxed).unwrap();
    let mut out = backend.download(&[&boxed, &sums]).unwrap();
    let sums = out.pop().unwrap();
    (out.pop().unwrap(), sums)
}

/// The local-correlation cost's kernels through a warp (lncc_terms, the box sums of its terms,
/// lncc_gradient; as similarity::LnccCost chains them), on both backends; a slab without
/// source data.
#[test]
fn local_correlation_cost_kernels_parity() {
    let Some(gpu) = gpu() else { return };
    let grid = oblique_grid([19, 14, 11]);
    let (moving, fixed) = (smooth_volume(&grid, 23), smooth_volume(&grid, 24));
    let slice = grid.dims[0] * grid.dims[1];
    let covered: Vec<f32> = (0..grid.len())
        .map(|n| (n / slice > 1) as u8 as f32)
        .collect();
    let step = [3, 2, 3];
    let ldims: [usize; 3] = std::array::from_fn(|a| (grid.dims[a] - 1).div_ceil(step[a]) + 1);
    let lattice: Vec<f32> = (0..3 * ldims.iter().product::<usize>())
        .map(|k| ((k * 37) % 23) as f32 * 0.05 - 0.5)
        .collect();
    let images = [&moving.data, &fixed.data, &covered, &lattice];
    let want = lncc_cost_outputs(&CpuBackend, &grid, images, ldims, step);
    let got = lncc_cost_outputs(gpu, &grid, images, ldims, step);
    let wide = |v: &[f32]| v.iter().map(|&x| x as f64).collect::<Vec<f64>>();
    // Equal to the bit on lavapipe (measured). A driver that fuses multiply-adds moves the box
    // sums of ≤ 125 products of values ~100 by a few ulps, and a window's variance Σa²/n − m²
    // loses to cancellation what its mean square exceeds it by: terms, which divide by two
    // variances, moved by 4.4e-4 of the largest on an NVIDIA H200.
    for (k, name) in ["terms", "rows", "gradient"].iter().enumerate() {
        close_f64(name, &wide(&got[k]), &wide(&want[k]), 2e-3);
    }
    assert!(
        want[2].iter().any(|&g| g != 0.0),
        "a gradient that is all zero tests nothing"
    );
}

/// lncc_terms' two outputs and lncc_gradient's, of `images` (moving, fixed, coverage, lattice).
fn lncc_cost_outputs<B: Backend>(
    b: &B,
    grid: &Grid,
    images: [&Vec<f32>; 4],
    ldims: [usize; 3],
    step: [usize; 3],
) -> Vec<Vec<f32>> {
    use posereg::abi::{LnccTermsParams, RbfGradParams};
    let [moving, fixed, covered, lattice] =
        images.map(|v| b.upload("an input", v.clone()).unwrap());
    let params = RbfGradParams::new(grid, ldims, step);
    let warped = b.warp_image(&params, &lattice, &moving).unwrap();
    let sums = box_sums(b, &LocalMomentsParams::passes(grid, 2), &warped, &fixed).unwrap();
    let (terms, rows) = b
        .lncc_terms(&LnccTermsParams::new(grid, 2, 1.0), &sums, &covered)
        .unwrap();
    let stack = LocalMomentsParams::stack_passes(grid, 2);
    let summed = box_sums(b, &stack, &terms, &terms).unwrap();
    let gradient = b
        .lncc_gradient(&params, &lattice, &moving, &fixed, &summed)
        .unwrap();
    b.download(&[&terms, &rows, &gradient]).unwrap()
}

/// The flagged values of an array and their indices, listed chunk by chunk where each backend
/// computes: the same list on both, and the host's own filter of the array, at a length that
/// leaves the last chunk short.
#[test]
fn flagged_values_are_listed_in_index_order() {
    let values: Vec<f32> = (0..5000u32)
        .map(|k| match (k * 7919) % 10 {
            0..=6 => 0.0,
            r => (r - 6) as f32 - (k % 3 == 0) as u8 as f32 * 4.5,
        })
        .collect();
    let want: Vec<(u32, f32)> = (0..values.len() as u32)
        .zip(values.iter().copied())
        .filter(|&(_, v)| v > 0.0)
        .collect();
    assert!(want.len() > 500 && values.iter().any(|&v| v < 0.0));
    let listed =
        |got: (Vec<u32>, Vec<f32>)| -> Vec<(u32, f32)> { got.0.into_iter().zip(got.1).collect() };
    let cpu = posereg::backend::reduce::flagged(
        &CpuBackend,
        &std::sync::Arc::new(values.clone()),
        values.len(),
    )
    .unwrap();
    assert_eq!(listed(cpu), want);
    let Some(gpu) = gpu() else { return };
    let on_gpu = gpu.upload("values", values.clone()).unwrap();
    let got = posereg::backend::reduce::flagged(gpu, &on_gpu, values.len()).unwrap();
    assert_eq!(listed(got), want);
}

/// The boundary voxels of two regions on an odd grid: a 5×5×5 cube (its 98 outer voxels) and
/// the slab beside it (where it touches the cube and the grid's inside), the same on both
/// backends.
#[test]
fn region_surfaces_parity() {
    let grid = oblique_grid([9, 8, 7]);
    let [nx, ny, _] = grid.dims;
    let regions: Vec<f32> = (0..grid.len())
        .map(|v| {
            let (i, j, k) = (v % nx, v / nx % ny, v / (nx * ny));
            match (i, j, k) {
                (1..=5, 1..=5, 1..=5) => 2.0,
                (7.., _, _) => 1.0,
                _ => 0.0,
            }
        })
        .collect();
    let params = posereg::abi::SurfaceParams::new(&grid);
    let cpu = CpuBackend
        .region_surface(&params, &std::sync::Arc::new(regions.clone()))
        .unwrap()
        .to_vec();
    let cube = cpu.iter().filter(|&&s| s == 2.0).count();
    assert_eq!(cube, 125 - 27, "the cube's outer voxels");
    // The slab x ≥ 7 meets other values only at x = 7 (the grid's faces are not boundaries).
    let slab: Vec<usize> = (0..grid.len()).filter(|&v| cpu[v] == 1.0).collect();
    assert_eq!(slab.len(), ny * grid.dims[2]);
    assert!(slab.iter().all(|&v| v % nx == 7));
    let Some(gpu) = gpu() else { return };
    let up = gpu.upload("regions", regions.clone()).unwrap();
    let got = gpu
        .download_one(&gpu.region_surface(&params, &up).unwrap())
        .unwrap();
    assert_eq!(got, cpu);
}

/// The round trip's statistics per chunk of source voxels on both backends, and their totals
/// against the host's own count over the body (source > 0): residuals with and without a
/// preimage (< 0), some beyond 0.1 mm, at a length that leaves the last chunk short.
#[test]
fn round_trip_statistics_parity() {
    use posereg::abi::{RoundTripParams, ROUND_TRIP_WIDTH};
    let voxels = 3000;
    let residual: Vec<f32> = (0..voxels)
        .map(|k| ((k * 7919) % 997) as f32 * 2e-4 - 0.02)
        .collect();
    let source: Vec<f32> = (0..voxels).map(|k| (k % 5) as f32 - 1.0).collect();
    let params = RoundTripParams::new(voxels, 0.1);
    let totals = |stats: &[f64]| -> [f64; ROUND_TRIP_WIDTH] {
        stats.chunks(ROUND_TRIP_WIDTH).fold([0.0; 5], |t, c| {
            [
                t[0] + c[0],
                t[1].max(c[1]),
                t[2] + c[2],
                t[3] + c[3],
                t[4] + c[4],
            ]
        })
    };
    let cpu = CpuBackend
        .round_trip_stats(
            &params,
            &std::sync::Arc::new(residual.clone()),
            &std::sync::Arc::new(source.clone()),
        )
        .unwrap();
    let inside: Vec<f32> = (0..voxels)
        .filter(|&k| source[k] > 0.0)
        .map(|k| residual[k])
        .collect();
    let seen: Vec<f32> = inside.iter().copied().filter(|&r| r >= 0.0).collect();
    let want = [
        seen.iter().map(|&r| r as f64).sum::<f64>(),
        seen.iter().fold(0.0f64, |m, &r| m.max(r as f64)),
        seen.len() as f64,
        seen.iter().filter(|&&r| r > 0.1).count() as f64,
        (inside.len() - seen.len()) as f64,
    ];
    let got = totals(&cpu);
    assert!((got[0] - want[0]).abs() < 1e-9 * want[0]);
    assert_eq!(got[1..], want[1..]);
    assert!(
        want[3] > 0.0 && want[4] > 0.0,
        "the fixture has far voxels and voxels without a preimage"
    );
    let Some(gpu) = gpu() else { return };
    let stats = gpu
        .round_trip_stats(
            &params,
            &gpu.upload("residual", residual).unwrap(),
            &gpu.upload("source", source).unwrap(),
        )
        .unwrap();
    assert_eq!(gpu.download_one(&stats).unwrap(), cpu.to_vec());
}

/// An empty buffer comes back empty (a list of no flagged voxels, for one): the staging
/// buffer is never empty, and its padding is not read as values.
#[test]
fn an_empty_download_is_empty() {
    let flags = vec![0.0f32; 3000];
    let listed = posereg::backend::reduce::flagged(
        &CpuBackend,
        &std::sync::Arc::new(flags.clone()),
        flags.len(),
    )
    .unwrap();
    assert!(listed.0.is_empty() && listed.1.is_empty());
    let Some(gpu) = gpu() else { return };
    let up = gpu.upload("flags", flags.clone()).unwrap();
    let listed = posereg::backend::reduce::flagged(gpu, &up, flags.len()).unwrap();
    assert!(listed.0.is_empty() && listed.1.is_empty());
}
