//! Helpers shared by the integration tests: seeded smooth data, the GPU backend, the binary.
#![allow(dead_code)] // each test binary uses a different subset

use posereg::gpu::GpuBackend;
use posereg::volume::{Affine, Field, Grid, Image, Volume};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::ffi::OsStr;
use std::process::{Command, Output};
use std::sync::OnceLock;

/// Runs the posereg binary with `args` (Mesa's runtime folder set, so it stays quiet).
pub fn posereg<S: AsRef<OsStr>>(args: &[S]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_posereg"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("the binary runs")
}

/// The GPU backend shared by a test binary, or None when there is no adapter. With
/// REQUIRE_GPU=1 (CI sets it) a missing adapter fails the test instead of skipping it.
pub fn gpu() -> Option<&'static GpuBackend> {
    static GPU: OnceLock<Option<GpuBackend>> = OnceLock::new();
    GPU.get_or_init(|| match GpuBackend::new() {
        Ok(b) => Some(b),
        Err(e) => {
            if std::env::var("REQUIRE_GPU").as_deref() == Ok("1") {
                panic!("REQUIRE_GPU=1 but the GPU backend failed: {e}");
            }
            eprintln!("GPU tests skipped: {e}");
            None
        }
    })
    .as_ref()
}

/// An oblique, anisotropic affine: rotation about two axes, zooms, offset.
pub fn oblique_affine(zooms: [f64; 3]) -> Affine {
    let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.5);
    let mut a = Affine::identity();
    for c in 0..3 {
        for r_ in 0..3 {
            a[(r_, c)] = r[(r_, c)] * zooms[c];
        }
    }
    a[(0, 3)] = -20.5;
    a[(1, 3)] = 13.0;
    a[(2, 3)] = 4.25;
    a
}

/// A grid of `dims` with an oblique anisotropic affine.
pub fn oblique_grid(dims: [usize; 3]) -> Grid {
    Grid::new(dims, oblique_affine([1.1, 0.9, 1.7])).unwrap()
}

/// A smooth random volume: a sum of seeded random sinusoids over the voxel index, plus an
/// offset so values are well away from zero (range about 20..180).
pub fn smooth_volume(grid: &Grid, seed: u64) -> Volume {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let waves: Vec<([f32; 3], f32, f32)> = (0..4)
        .map(|_| {
            let k = [
                rng.random_range(0.05..0.5f32),
                rng.random_range(0.05..0.5f32),
                rng.random_range(0.05..0.5f32),
            ];
            (
                k,
                rng.random_range(0.0..std::f32::consts::TAU),
                rng.random_range(10.0..20.0f32),
            )
        })
        .collect();
    let [nx, ny, nz] = grid.dims;
    let mut data = Vec::with_capacity(grid.len());
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = [i as f32, j as f32, k as f32];
                let v: f32 = waves
                    .iter()
                    .map(|(w, phase, amp)| {
                        amp * (w[0] * p[0] + w[1] * p[1] + w[2] * p[2] + phase).sin()
                    })
                    .sum();
                data.push(100.0 + v);
            }
        }
    }
    Image::from_data(grid.clone(), data).unwrap()
}

/// A smooth random displacement field (mm) of amplitude up to `amplitude` per component.
pub fn smooth_field(grid: &Grid, seed: u64, amplitude: f32) -> Field {
    let comps: Vec<Volume> = (0..3).map(|c| smooth_volume(grid, seed * 3 + c)).collect();
    let data = (0..grid.len())
        .map(|i| std::array::from_fn(|c| (comps[c].data[i] - 100.0) / 60.0 * amplitude))
        .collect();
    Image::from_data(grid.clone(), data).unwrap()
}

/// A constant displacement field.
pub fn constant_field(grid: &Grid, d: [f32; 3]) -> Field {
    Image::filled(grid.clone(), d)
}

/// Largest |a - b| over two equally long slices.
pub fn max_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// `volume` one pyramid level down, built by `backend` and brought back.
pub fn one_level_down<B: posereg::Backend>(backend: &B, volume: &Volume) -> Volume {
    let image =
        posereg::backend::DeviceImage::upload(backend, "test volume", volume.clone()).unwrap();
    let mut levels = posereg::images::pyramid::build(backend, image, 2).unwrap();
    assert_eq!(levels.len(), 2, "the grid can be halved");
    levels.pop().unwrap().download(backend).unwrap()
}

/// Per-cell SSD of `a` against `b` where `covered` (≥ abi::COVERED_AT) says `a` holds data.
pub fn cell_ssd<B: posereg::Backend>(
    backend: &B,
    (a, b, covered): (&Volume, &Volume, &[f32]),
    cells: [usize; 3],
) -> posereg::images::metric::CellSsd {
    let up = |v: &[f32]| backend.upload("test volume", v.to_vec()).unwrap();
    let (a_data, b_data, c_data) = (up(&a.data), up(&b.data), up(covered));
    let images = posereg::backend::CostImages {
        moving: &a_data,
        fixed: &b_data,
        covered: &c_data,
    };
    let dims = a.grid.dims;
    let partial = backend
        .ssd_cells(&posereg::abi::SsdParams::new(dims, cells), &images)
        .unwrap();
    let partial = backend.download_one(&partial).unwrap();
    posereg::images::metric::fold_ssd_partials(dims, cells, &partial)
}

#[allow(unused_imports)]
pub use posereg::backend::resample_volume;
#[allow(unused_imports)]
pub use posereg::images::fold_repair::host_determinant;

/// Skinning weights (bones per voxel) from host distances (one volume per bone, reach 1),
/// brought back.
pub fn skin_weights<B: posereg::Backend>(
    backend: &B,
    distances: &[f32],
    grid: &Grid,
    bones: usize,
    power: u32,
) -> posereg::Result<Vec<f32>> {
    let params = posereg::abi::SkinWeightsParams::new(grid, &vec![1.0; bones], power);
    let distances = backend.upload("distances", distances.to_vec())?;
    backend.download_one(&backend.skin_weights(&params, &distances)?)
}

/// The inverted blend from host inputs, brought back as 4 floats per target voxel (u, then the
/// residual).
pub fn skin_blend<B: posereg::Backend>(
    backend: &B,
    weights: &[f32],
    weight_grid: &Grid,
    bone_of_voxel: &[f32],
    labels: &Grid,
    target: &Grid,
    blend: &posereg::abi::BoneBlend,
) -> posereg::Result<Vec<f32>> {
    let params = posereg::abi::SkinBlendParams::new(target, weight_grid, labels, blend);
    let weights = backend.upload("weights", weights.to_vec())?;
    let bone_of_voxel = backend.upload("bone of voxel", bone_of_voxel.to_vec())?;
    let (field, residual) = backend.skin_blend(&params, &weights, &bone_of_voxel)?;
    let mut host = backend.download(&[&field, &residual])?;
    let (residual, field) = (host.pop().unwrap(), host.pop().unwrap());
    Ok(field
        .chunks(3)
        .zip(residual)
        .flat_map(|(u, r)| [u[0], u[1], u[2], r])
        .collect())
}

/// The initial field's mean error over `body` against `truth_field` with each reach limit of
/// the default candidates fixed, and with the default choice among them: (limit, error) per
/// fixed limit, then (the limit chosen, its error). The bones start at `truth` so that only
/// the reach differs.
pub fn initial_error_by_reach(
    (source, labels, target): (&Volume, &posereg::Labels, &Volume),
    truth: &posereg::io::transform::BoneTransforms,
    truth_field: &Field,
    body: &[bool],
) -> (Vec<(f64, f64)>, (f64, f64)) {
    use posereg::init::articulated::{initialise_volumes, InitOptions, Start};
    let run = |reach: Vec<f64>| {
        let options = InitOptions {
            reach,
            ..InitOptions::default()
        };
        let start = Some(Start::Given(truth));
        let backend = &posereg::cpu::CpuBackend;
        let silent = &posereg::progress::Silent;
        let (init, images) =
            initialise_volumes(backend, source, labels, target, &options, start, silent).unwrap();
        let error = posereg::report::evaluate::field_error(&images.field, truth_field, |n| body[n]);
        (init.reach.limit, error.unwrap().mean_mm)
    };
    let candidates = InitOptions::default().reach;
    let fixed = candidates.iter().map(|&l| run(vec![l])).collect();
    (fixed, run(candidates))
}
