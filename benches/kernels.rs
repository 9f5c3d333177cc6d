//! Kernel benchmarks: each kernel × backend (CPU twin, GPU) × size, throughput in voxels/s.
//! Most rows time a kernel called on host data (upload, dispatch, submit, wait, read-back:
//! `resident`); the non-rigid evaluation's rows run on resident buffers and include only the
//! submit, the wait and a small read-back.
//!
//! Sizes: POSEREG_BENCH_SIZES=tiny (CI smoke: 16³), =small (64³, 128³), default all three of
//! 64³, 128³ and the paper's 136×256×256.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use posereg::abi::dense::{CombineParams, ForceParams, ForceTerm, NormParams};
use posereg::abi::{
    pack_candidates, BoneLookupParams, ComposeParams, DilateParams, EdtParams, EdtRegions,
    FadeParams, GainParams, Interpolation, InvertParams, JacobianParams, LabelParams, LnccParams,
    LocalMomentsParams, MomentsParams, PyramidParams, RbfGradParams, ResampleParams, RigidParams,
    ScoreParams, SkinBlendParams, SkinWeightsParams, SsdParams, SumParams, ThresholdParams,
    RIGID_SUMS, SCORE_SUMS,
};
use posereg::backend::dense::ForceImages;
use posereg::backend::prelude::*;
use posereg::backend::{box_sums, BoneImages, CostImages, DeviceImage};
use posereg::cpu::CpuBackend;
use posereg::device::Opened;
use posereg::gpu::GpuBackend;
use posereg::images::similarity::LnccCost;
use posereg::images::unfold::{unfold, Bones, Held};
use posereg::volume::{Affine, Grid, Image};

fn sizes() -> Vec<[usize; 3]> {
    match std::env::var("POSEREG_BENCH_SIZES").as_deref() {
        Ok("tiny") => vec![[16, 16, 16]],
        Ok("small") => vec![[64, 64, 64], [128, 128, 128]],
        _ => vec![[64, 64, 64], [128, 128, 128], [256, 256, 136]],
    }
}

fn grid(dims: [usize; 3]) -> Grid {
    let mut a = Affine::identity();
    a[(2, 2)] = 1.2;
    Grid::new(dims, a).unwrap()
}

/// Seeded smooth data: a deterministic pattern (no RNG needed for throughput).
fn volume(g: &Grid, phase: f32) -> posereg::Volume {
    let [nx, ny, _] = g.dims;
    let data = (0..g.len())
        .map(|i| {
            let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
            100.0
                + 30.0
                    * ((x as f32 * 0.11 + phase).sin()
                        + (y as f32 * 0.07).cos()
                        + (z as f32 * 0.13).sin())
        })
        .collect();
    Image::from_data(g.clone(), data).unwrap()
}

fn field(g: &Grid) -> posereg::Field {
    let [nx, ny, _] = g.dims;
    let data = (0..g.len())
        .map(|i| {
            let (x, y) = ((i % nx) as f32, ((i / nx) % ny) as f32);
            [2.0 * (y * 0.05).sin(), 1.5 * (x * 0.04).cos(), 0.7]
        })
        .collect();
    Image::from_data(g.clone(), data).unwrap()
}

fn backends() -> Vec<(&'static str, Opened)> {
    let mut list: Vec<(&'static str, Opened)> = vec![("cpu", Opened::Cpu(CpuBackend))];
    match GpuBackend::new() {
        Ok(g) => {
            eprintln!("gpu backend: {}", g.describe());
            list.push(("gpu", Opened::Gpu(Box::new(g))));
        }
        Err(e) if std::env::var("REQUIRE_GPU").as_deref() == Ok("1") => {
            panic!("REQUIRE_GPU=1 but no GPU backend: {e}")
        }
        Err(e) => eprintln!("gpu benches skipped: {e}"),
    }
    list
}

/// One benchmark group: `run` on every backend at one size. A backend whose device cannot hold
/// the inputs (posereg's `DeviceLimit` error, e.g. lavapipe's 128 MiB binding limit at the
/// paper's size) is skipped with the error printed; any other error fails the bench.
fn group<R>(
    c: &mut Criterion,
    title: &str,
    elements: u64,
    label: &str,
    backends: &[(&'static str, Opened)],
    run: impl Fn(&Opened) -> posereg::Result<R>,
) {
    let mut group = c.benchmark_group(title);
    group
        .sample_size(10)
        .throughput(Throughput::Elements(elements));
    for (name, b) in backends {
        // Only a device has limits to probe; the CPU twins are not run an extra time.
        let probe = || match *name {
            "gpu" => run(b).map(|_| ()),
            _ => Ok(()),
        };
        match probe() {
            Err(e @ posereg::Error::DeviceLimit { .. }) => {
                eprintln!("{title}/{name}/{label} skipped: {e}");
                continue;
            }
            Err(e) => panic!("{title}/{name}/{label}: {e}"),
            Ok(()) => {}
        }
        group.bench_with_input(BenchmarkId::new(*name, label), &(), |bench, _| {
            bench.iter(|| run(b).unwrap())
        });
    }
    group.finish();
}

/// Uploads `inputs`, runs `kernels` on them and downloads what they return: a kernel's cost
/// when called on host data.
fn resident<B: Backend, T: posereg::backend::Element, const N: usize>(
    b: &B,
    inputs: &[&Vec<f32>; N],
    kernels: impl Fn(&B, [&B::Buffer<f32>; N]) -> posereg::Result<B::Buffer<T>>,
) -> posereg::Result<Vec<T>> {
    let buffers = inputs
        .iter()
        .map(|v| b.upload("bench input", v.to_vec()))
        .collect::<posereg::Result<Vec<_>>>()?;
    let out = kernels(b, std::array::from_fn(|k| &buffers[k]))?;
    b.download_one(&out)
}

/// The label lookups and the fold repair's kernels, on `field` (3 floats per voxel of `g`)
/// and a label map of runs of codes 0..6; bones 2 and 3.
fn label_and_fold_rows(
    c: &mut Criterion,
    g: &Grid,
    label: &str,
    backends: &[(&'static str, Opened)],
    field: &Vec<f32>,
) {
    let labels: Vec<f32> = (0..g.len()).map(|n| ((n / 3) % 7) as f32).collect();
    let zeros = vec![0.0f32; g.len()];
    let codes = LabelParams::new(g, &[2, 3]).unwrap();
    group(
        c,
        "label_index",
        g.len() as u64,
        label,
        backends,
        |b| posereg::on_backend!(b, b => resident(b, &[&labels], |b, [l]| b.label_index(&codes, l))),
    );
    let lookup = BoneLookupParams::new(g, g, &[2, 3], f32::MAX).unwrap();
    group(c, "bone_at_source", g.len() as u64, label, backends, |b| {
        posereg::on_backend!(b, b => resident(b, &[field, &zeros, &labels], |b, [f, r, l]| {
            b.bone_at_source(&lookup, f, r, l)
        }))
    });
    // A determinant folded on one voxel in 50; nothing held.
    let det: Vec<f32> = (0..g.len())
        .map(|n| if n % 50 == 0 { -0.1 } else { 1.0 })
        .collect();
    let folds = ThresholdParams::new(g, 0.05);
    group(c, "fold_stats", g.len() as u64, label, backends, |b| {
        posereg::on_backend!(b, b => resident(b, &[&det, &zeros], |b, [d, h]| {
            b.fold_stats(&folds, d, h)
        }))
    });
    group(c, "mark_at_most", g.len() as u64, label, backends, |b| {
        posereg::on_backend!(b, b => resident(b, &[&det, &zeros], |b, [d, h]| {
            b.mark_at_most(&folds, d, h)
        }))
    });
    let marked: Vec<f32> = det.iter().map(|&d| (d <= 0.05) as u8 as f32).collect();
    let passes = DilateParams::passes(g, 2);
    group(c, "dilate_3_passes", g.len() as u64, label, backends, |b| {
        posereg::on_backend!(b, b => resident(b, &[&marked, &zeros], |b, [m, h]| {
            let x = b.dilate(&passes[0], m, h)?;
            let y = b.dilate(&passes[1], &x, h)?;
            b.dilate(&passes[2], &y, h)
        }))
    });
    let region: Vec<f32> = (0..g.len()).map(|n| (n % 5 == 0) as u8 as f32).collect();
    if let Ok(passes) = EdtParams::passes(g, EdtRegions::Each(2)) {
        group(
            c,
            "edt_2_regions_3_passes",
            g.len() as u64,
            label,
            backends,
            |b| {
                posereg::on_backend!(b, b => resident(b, &[&labels], |b, [l]| {
                    let x = b.edt(&passes[0], l)?;
                    let y = b.edt(&passes[1], &x)?;
                    b.edt(&passes[2], &y)
                }))
            },
        );
    }
    let moments = MomentsParams::new(g, 0.5);
    group(
        c,
        "moments",
        g.len() as u64,
        label,
        backends,
        |b| posereg::on_backend!(b, b => resident(b, &[&region], |b, [r]| b.moments(&moments, r))),
    );
    group(c, "fold_smooth", g.len() as u64, label, backends, |b| {
        posereg::on_backend!(b, b => resident(b, &[field, &region, &labels], |b, [f, r, l]| {
            b.fold_smooth(&lookup, f, r, l)
        }))
    });
    // The whole fold push (images::unfold: fold_candidates, then fold_push, fold_refresh and
    // fold_advance sweep after sweep) on a field folded in a ball at the centre; no bones.
    let folded = ball_fold(g);
    group(
        c,
        "fold_push_ball",
        g.len() as u64,
        label,
        backends,
        |b| posereg::on_backend!(b, b => push_ball(b, g, &folded, &lookup)),
    );
}

/// A field that folds in a ball of radius 6 voxels at the grid's centre: pulled towards the
/// centre by 1.6 times its offset there (det J = (1 - 1.6)³ < 0), fading out to the rim.
fn ball_fold(g: &Grid) -> Vec<f32> {
    let [nx, ny, _] = g.dims;
    let centre = g.dims.map(|n| n as f32 / 2.0);
    let spacing = g.spacing().map(|s| s as f32);
    let mut u = vec![0.0f32; 3 * g.len()];
    for (v, u) in u.chunks_exact_mut(3).enumerate() {
        let p = [v % nx, v / nx % ny, v / (nx * ny)].map(|i| i as f32);
        let d: [f32; 3] = std::array::from_fn(|a| p[a] - centre[a]);
        let r2 = d.iter().map(|x| x * x).sum::<f32>() / 36.0;
        if r2 < 1.0 {
            let fade = (1.0 - r2) * (1.0 - r2);
            (0..3).for_each(|a| u[a] = -1.6 * d[a] * spacing[a] * fade);
        }
    }
    u
}

/// Pushes `field`'s folds on `b` (nothing held, no bone in the labels) and waits for the
/// pushed field.
fn push_ball<B: Backend>(
    b: &B,
    g: &Grid,
    field: &[f32],
    lookup: &BoneLookupParams,
) -> posereg::Result<usize> {
    let field = DeviceImage {
        grid: g.clone(),
        data: b.upload("bench field", field.to_vec())?,
    };
    let none = b.zeros("bench nothing held", g.len())?;
    let held = Held {
        bones: &none,
        rigid: &none,
    };
    let bones = Bones {
        lookup,
        labels: &none,
    };
    let det = b.jacobian(&JacobianParams::new(g), &field.data)?;
    let (pushed, sweeps) = unfold(b, (&field, &det), &held, &bones)?;
    b.download_one(&pushed.data)?;
    Ok(sweeps)
}

/// The non-rigid rows' spline's affine part (translation, then the linear rows, mm): a warp of
/// half a millimetre and 1%, like an adaptive step's, so that almost every warped point stays
/// inside the image (a larger one sent most outside, and warp_cost timed its early out).
const SMALL_AFFINE: [[f64; 3]; 4] = [
    [0.5, -0.3, 0.2],
    [0.01, 0.0, 0.0],
    [0.0, -0.01, 0.0],
    [0.0, 0.0, 0.01],
];

/// The non-rigid evaluation's kernels on resident buffers (lattice every 4 voxels, 100 control
/// points), each timed with the download of a small output that depends on it, and the whole
/// chain as one evaluation (what the optimiser pays per step).
fn nonrigid_rows<B: Backend>(c: &mut Criterion, name: &str, b: &B, g: &Grid, label: &str) {
    use posereg::abi::{
        lattice_geometry, spline_buffer, RbfGradParams, RbfLatticeParams, SplatParams,
    };
    let step = [4; 3];
    let ldims: [usize; 3] = std::array::from_fn(|a| (g.dims[a] - 1).div_ceil(step[a]) + 1);
    let points = 100;
    let centres: Vec<[f64; 3]> = (0..points)
        .map(|p| {
            let f = |k: usize, n: usize| ((p * 7919 + k * 104729) % n) as f64;
            g.voxel_to_world([f(0, g.dims[0]), f(1, g.dims[1]), f(2, g.dims[2])])
        })
        .collect();
    let lambda: Vec<[f64; 3]> = (0..points)
        .map(|p| [1e-8 * (p % 7) as f64, -1e-8, 2e-8 * (p % 3) as f64])
        .collect();
    let shape = RbfLatticeParams::new(ldims, step, points);
    let up = |what, v: Vec<f32>| b.upload(what, v).unwrap();
    let moving = up("moving", volume(g, 0.0).data);
    let fixed = up("fixed", volume(g, 0.5).data);
    let covered = up("covered", vec![1.0; g.len()]);
    let images = posereg::backend::CostImages {
        moving: &moving,
        fixed: &fixed,
        covered: &covered,
    };
    let geometry = b.upload("geometry", lattice_geometry(g)).unwrap();
    let spline = b
        .upload("spline", spline_buffer(&SMALL_AFFINE, &centres, &lambda))
        .unwrap();
    let warp_params = RbfGradParams::new(g, ldims, step);
    let splat_params = SplatParams::new(ldims, step, g.dims);
    let h = g.spacing();
    let spacing: [f64; 3] = std::array::from_fn(|a| h[a] * step[a] as f64);
    let energy = posereg::nonrigid::regularise::energy_params(ldims, spacing, 3.0, 0.0, 1e-6);
    let warp = b.rbf_lattice(&shape, &geometry, &spline).unwrap();
    let (per_voxel, rows) = b.warp_cost(&warp_params, &warp, &images).unwrap();
    let splat = b.lattice_splat(&splat_params, &per_voxel).unwrap();
    let (node_gradient, _) = b.lattice_energy(&energy, &warp, &splat).unwrap();
    let voxels = Throughput::Elements(g.len() as u64);
    let mut group = c.benchmark_group("nonrigid evaluation");
    group.sample_size(10).throughput(voxels);
    let id = |kernel: &str| BenchmarkId::new(format!("{kernel}/{name}"), label);
    group.bench_function(id("rbf_lattice"), |t| {
        t.iter(|| b.download(&[&b.rbf_lattice(&shape, &geometry, &spline).unwrap()]))
    });
    group.bench_function(id("warp_cost"), |t| {
        t.iter(|| b.download(&[&b.warp_cost(&warp_params, &warp, &images).unwrap().1]))
    });
    group.bench_function(id("lattice_splat"), |t| {
        t.iter(|| b.download(&[&b.lattice_splat(&splat_params, &per_voxel).unwrap()]))
    });
    group.bench_function(id("lattice_energy"), |t| {
        t.iter(|| b.download(&[&b.lattice_energy(&energy, &warp, &splat).unwrap().1]))
    });
    group.bench_function(id("rbf_adjoint"), |t| {
        t.iter(|| {
            let partials = b
                .rbf_adjoint(&shape, &geometry, &spline, &node_gradient)
                .unwrap();
            b.download(&[&b.sum_partials(&partials, 3 * shape.rows()).unwrap()])
        })
    });
    group.bench_function(id("whole evaluation"), |t| {
        t.iter(|| {
            let warp = b.rbf_lattice(&shape, &geometry, &spline).unwrap();
            let (per_voxel, rows) = b.warp_cost(&warp_params, &warp, &images).unwrap();
            let splat = b.lattice_splat(&splat_params, &per_voxel).unwrap();
            let (node_gradient, terms) = b.lattice_energy(&energy, &warp, &splat).unwrap();
            let partials = b
                .rbf_adjoint(&shape, &geometry, &spline, &node_gradient)
                .unwrap();
            let adjoint = b.sum_partials(&partials, 3 * shape.rows()).unwrap();
            let sums = [
                b.sum_chunks(&SumParams::new(warp_params.rows()), &rows)
                    .unwrap(),
                b.sum_chunks(&SumParams::new(energy.nodes()), &terms)
                    .unwrap(),
            ];
            b.download(&[&adjoint, &sums[0], &sums[1]])
        })
    });
    drop(rows);
    group.finish();
}

/// The intensity gain's kernels: the terms on the grid, the ratio and the application from a
/// grid one pyramid level coarser.
fn gain_rows(
    c: &mut Criterion,
    g: &Grid,
    label: &str,
    backends: &[(&'static str, Opened)],
    (source, target): (&posereg::Volume, &posereg::Volume),
) {
    let (coarse, _) = posereg::images::pyramid::next_level_grid(g).unwrap();
    let fine = GainParams::new(g, g, 0.0, 2.0);
    group(c, "gain_terms", g.len() as u64, label, backends, |b| {
        posereg::on_backend!(b, b => resident(b, &[&source.data, &target.data], |b, [s, t]| {
            Ok(b.gain_terms(&fine, s, t)?.0)
        }))
    });
    let ratio = GainParams::new(&coarse, &coarse, 1.0, 2.0);
    let (p, e) = (volume(&coarse, 0.0), volume(&coarse, 0.3));
    group(c, "gain_ratio", coarse.len() as u64, label, backends, |b| {
        posereg::on_backend!(b, b => resident(b, &[&p.data, &e.data], |b, [p, e]| {
            b.gain_ratio(&ratio, p, e)
        }))
    });
    let apply = GainParams::new(g, &coarse, 1.0, 2.0);
    group(c, "gain_apply", g.len() as u64, label, backends, |b| {
        posereg::on_backend!(b, b => resident(b, &[&e.data, &source.data], |b, [gain, m]| {
            b.gain_apply(&apply, gain, m)
        }))
    });
}

fn kernels(c: &mut Criterion) {
    let backends = backends();
    for dims in sizes() {
        let g = grid(dims);
        let source = volume(&g, 0.0);
        let target = volume(&g, 0.5);
        let u = field(&g);
        let label = format!("{}x{}x{}", dims[0], dims[1], dims[2]);
        let uf: Vec<f32> = bytemuck::cast_slice(&u.data).to_vec();
        let ones = vec![1.0f32; g.len()];
        let sample = ResampleParams::new(&g, &g, 0.0, Interpolation::Linear);
        group(c, "resample", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&source.data, &uf], |b, [s, f]| {
                b.resample(&sample, s, f)
            }))
        });
        group(
            c,
            "coverage",
            g.len() as u64,
            &label,
            &backends,
            |b| posereg::on_backend!(b, b => resident(b, &[&uf, &ones], |b, [f, m]| b.coverage(&sample, f, m))),
        );
        group(c, "jacobian", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&uf], |b, [f]| {
                b.jacobian(&JacobianParams::new(&g), f)
            }))
        });
        label_and_fold_rows(c, &g, &label, &backends, &uf);
        // The local correlation of two images (radius 2): three box-sum passes and the ρ² sums.
        let passes = LocalMomentsParams::passes(&g, 2);
        let lncc = LnccParams::new(&g, 2);
        group(
            c,
            "local_correlation",
            g.len() as u64,
            &label,
            &backends,
            |b| {
                posereg::on_backend!(b, b => resident(b, &[&source.data, &target.data], |b, [s, t]| {
                    b.lncc(&lncc, &box_sums(b, &passes, t, s)?)
                }))
            },
        );
        let (coarse, factors) = posereg::images::pyramid::next_level_grid(&g).unwrap();
        let down = PyramidParams::new(&g, coarse.dims, factors);
        group(c, "pyramid", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&source.data], |b, [s]| {
                b.pyramid_level(&down, s)
            }))
        });
        // The non-rigid stage's per-iteration work: lattice every 4 voxels.
        let step = [4; 3];
        let ldims: [usize; 3] = std::array::from_fn(|a| (dims[a] - 1).div_ceil(step[a]) + 1);
        let lattice: Vec<f32> = (0..3 * ldims.iter().product::<usize>())
            .map(|k| ((k % 17) as f32 - 8.0) * 0.1)
            .collect();
        let warp = RbfGradParams::new(&g, ldims, step);
        group(c, "warp_image", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&lattice, &source.data], |b, [l, s]| {
                b.warp_image(&warp, l, s)
            }))
        });
        // The LNCC image term's evaluation through the warp (radius 2): the warped image, five
        // box-sum passes, lncc_terms and lncc_gradient, as warp_cost is for SSD.
        let lncc_cost = LnccCost::new(&g, 2, 1.0);
        let coverage: Vec<f32> = vec![1.0; g.len()];
        group(c, "lncc_cost", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&lattice, &source.data, &target.data, &coverage], |b, [l, s, t, c]| {
                let images = CostImages { moving: s, fixed: t, covered: c };
                Ok(lncc_cost.evaluate(b, &warp, l, &images)?.0)
            }))
        });
        gain_rows(c, &g, &label, &backends, (&source, &target));
        for (name, b) in &backends {
            posereg::on_backend!(b, b => nonrigid_rows(c, name, b, &g, &label));
        }
        let node_values: Vec<f32> = (0..3 * ldims.iter().product::<usize>())
            .map(|k| (k % 17) as f32 * 0.1)
            .collect();
        group(c, "warp_field", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&node_values], |b, [l]| {
                b.warp_field(&warp, l)
            }))
        });
        group(c, "compose", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&uf, &uf], |b, [r, u0]| {
                b.compose(&ComposeParams::new(&g, &g), r, u0)
            }))
        });
        // The distance to the nearest bone: the final field's warp held off the bones.
        let distances: Vec<f32> = (0..g.len()).map(|k| (k % 23) as f32).collect();
        group(c, "fade_warp", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&uf, &distances], |b, [r, d]| {
                b.fade_warp(&FadeParams::new(&g, 8.0), r, d)
            }))
        });
        // The dense refinement's family: a velocity smoothed (σ 1.8 voxels, three passes),
        // the LNCC force from the box sums, the update's largest vector, the faded update.
        group(
            c,
            "gauss_axis (3 passes, 3 components)",
            g.len() as u64,
            &label,
            &backends,
            |b| {
                posereg::on_backend!(b, b => resident(b, &[&uf], |b, [f]| {
                    posereg::backend::dense::smooth(b, &g, 3, 1.8, f)
                }))
            },
        );
        group(
            c,
            "dense_force (LNCC)",
            g.len() as u64,
            &label,
            &backends,
            |b| {
                posereg::on_backend!(b, b => resident(b, &[&source.data, &target.data], |b, [w, f]| {
                    let sums = box_sums(b, &LocalMomentsParams::passes(&g, 2), w, f)?;
                    let images = ForceImages { moving: w, fixed: f, covered: f, sums: &sums };
                    Ok(b.dense_force(&ForceParams::new(&g, ForceTerm::Lncc, 2), &images)?.0)
                }))
            },
        );
        group(c, "norm_max", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&uf], |b, [f]| {
                b.norm_max(&NormParams::new(&g), f)
            }))
        });
        group(
            c,
            "field_combine (faded)",
            g.len() as u64,
            &label,
            &backends,
            |b| {
                posereg::on_backend!(b, b => resident(b, &[&uf, &uf, &distances], |b, [v, u, d]| {
                    b.field_combine(&CombineParams::sum(&g, 1.0, 0.5).faded(4.0), v, u, d)
                }))
            },
        );
        group(c, "invert_field", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&uf], |b, [f]| {
                Ok(b.invert_field(&InvertParams::new(&g, &g), f)?.0)
            }))
        });
        // Articulated initialisation: a whole-volume bone region, a small motion.
        let mask: posereg::Volume = Image::filled(g.clone(), 1.0);
        let motion = posereg::init::rigid::small_motion(
            &nalgebra::Vector6::new(0.02, -0.01, 0.03, 1.0, -0.5, 0.2),
            &nalgebra::Vector3::zeros(),
        );
        group(c, "rigid_gn", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&source.data, &mask.data, &target.data], |b, [s, m, t]| {
                let params = RigidParams::new(&g, &g, &motion, [0.0; 3]);
                let partial = b.rigid_sums(&params, &BoneImages { source: s, mask: m, target: t })?;
                b.sum_partials(&partial, RIGID_SUMS)
            }))
        });
        let candidates: Vec<posereg::Affine> = (0..32)
            .map(|k| {
                posereg::init::rigid::small_motion(
                    &nalgebra::Vector6::new(0.0, 0.0, 0.01 * k as f64, 0.0, 0.0, 0.0),
                    &nalgebra::Vector3::zeros(),
                )
            })
            .collect();
        group(
            c,
            "rigid_score_32_candidates",
            32 * g.len() as u64,
            &label,
            &backends,
            |b| {
                posereg::on_backend!(b, b => resident(b, &[&source.data, &mask.data, &target.data], |b, [s, m, t]| {
                    let params = ScoreParams::new(&g, &g, candidates.len());
                    let packed = b.upload("candidates", pack_candidates(&candidates))?;
                    let images = BoneImages { source: s, mask: m, target: t };
                    let partial = b.rigid_scores(&params, &images, &packed)?;
                    b.sum_partials(&partial, SCORE_SUMS * candidates.len())
                }))
            },
        );
        let bones = 4;
        // Synthetic distances (mm) to each bone, per voxel of a grid of `voxels`.
        let synthetic_distances = |voxels: usize| -> Vec<f32> {
            (0..voxels * bones).map(|k| 1.0 + (k % 37) as f32).collect()
        };
        let distances = synthetic_distances(g.len());
        let weighting = SkinWeightsParams::new(&g, &vec![1.0; bones], 2);
        group(
            c,
            "skin_weights_4_bones",
            g.len() as u64,
            &label,
            &backends,
            |b| {
                posereg::on_backend!(b, b => resident(b, &[&distances], |b, [d]| {
                    b.skin_weights(&weighting, d)
                }))
            },
        );
        // Weights on the skinning grid (~2.5 mm), as the pipeline keeps them.
        let weight_grid = posereg::init::skinning::skinning_grid(&g);
        let weights = resident(
            &CpuBackend,
            &[&synthetic_distances(weight_grid.len())],
            |b, [d]| {
                b.skin_weights(
                    &SkinWeightsParams::new(&weight_grid, &vec![1.0; bones], 2),
                    d,
                )
            },
        )
        .unwrap();
        let soft_tissue = vec![0.0f32; g.len()];
        let blend = posereg::abi::BoneBlend {
            motions: (0..bones)
                .map(|k| {
                    posereg::init::rigid::small_motion(
                        &nalgebra::Vector6::new(0.1 * k as f64, 0.0, 0.0, 0.0, 0.0, 0.0),
                        &nalgebra::Vector3::new(0.0, 0.0, 10.0),
                    )
                })
                .collect(),
            blending: posereg::abi::Blending::Linear,
            iterations: 8,
        };
        let blending = SkinBlendParams::new(&g, &weight_grid, &g, &blend);
        group(
            c,
            "skin_blend_4_bones",
            g.len() as u64,
            &label,
            &backends,
            |b| {
                posereg::on_backend!(b, b => resident(b, &[&weights, &soft_tissue], |b, [w, s]| {
                    Ok(b.skin_blend(&blending, w, s)?.1)
                }))
            },
        );
        group(c, "ssd_cells_16", g.len() as u64, &label, &backends, |b| {
            posereg::on_backend!(b, b => resident(b, &[&source.data, &target.data, &vec![1.0; g.len()]], |b, [s, t, c]| {
                let images = CostImages { moving: s, fixed: t, covered: c };
                b.ssd_cells(&SsdParams::new(g.dims, [16, 16, 16]), &images)
            }))
        });
    }
}

criterion_group!(benches, kernels);
criterion_main!(benches);
