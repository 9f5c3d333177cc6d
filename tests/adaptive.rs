//! The paper's synthetic experiment (§4) at the paper's registration scale (34×64×64) and at a
//! small size (48×96×96): a phantom bent 10°, registered without the articulated initialisation, against the paper's figures (mean error ≤ 3.2 mm,
//! correlation ≥ 0.95, ≥ 87% within 2 voxels, ≥ 99.8% within 4), on both backends; and the
//! whole pipeline at 60°, where only the initialisation brings the bones within reach.

mod common;

use posereg::progress::Silent;

use nalgebra::Vector3;
use posereg::images::metric::correlation;
use posereg::images::similarity::Similarity;
use posereg::labels as label;
use posereg::levels::PerLevel;
use posereg::phantom::{generate, Phantom, PhantomSize, PhantomSpec};
use posereg::pipeline::register::{
    register, register_observed, Inputs, RegisterOptions, Registration,
};
use posereg::report::evaluate::{field_error, FieldError};
use posereg::{Backend, Field, Labels};
use std::sync::OnceLock;

fn pair(size: PhantomSize, flexion: f64) -> (Phantom, Phantom) {
    let spec = |flexion_degrees, seed| PhantomSpec {
        size,
        flexion_degrees,
        seed,
        ..Default::default()
    };
    (
        generate(&spec(0.0, 1)).unwrap(),
        generate(&spec(flexion, 2)).unwrap(),
    )
}

/// Body voxels whose true source point lies inside the source's field of view.
fn evaluation_mask(source: &Phantom, target: &Phantom) -> Vec<bool> {
    let seen =
        posereg::report::evaluate::seen_by_both(&target.truth_field, &source.image.grid, 0.0);
    seen.iter()
        .zip(&target.labels.data)
        .map(|(s, l)| *s && *l != label::OUTSIDE)
        .collect()
}

/// Registers the pair of `size` bent `flexion`° with `options` and scores it over the evaluation
/// mask: the field error against the truth, the correlation with the target, and the result.
fn register_and_score<B: Backend>(
    backend: &B,
    size: PhantomSize,
    flexion: f64,
    options: &RegisterOptions,
    name: &str,
) -> Scored {
    let (source, target) = pair(size, flexion);
    let mut initial = None;
    let result = register_observed(
        backend,
        Inputs::new(&source.image, &source.labels, &target.image),
        options,
        &Silent,
        &mut |images| {
            initial = Some(images.field.download_field(backend)?);
            Ok(())
        },
    )
    .unwrap();
    let mask = evaluation_mask(&source, &target);
    let inside = |n: usize| mask[n];
    let error = field_error(&result.field, &target.truth_field, inside).unwrap();
    let initial_error = initial
        .filter(|_| result.init.is_some())
        .map(|field| field_error(&field, &target.truth_field, inside).unwrap());
    let correlation = correlation(&result.warped.data, &target.image.data, inside);
    let points = result.adaptive.points.len();
    eprintln!(
        "{name} {size:?}: mean {:.2} mm, within 2 voxels {:.1}%, within 4 {:.2}%, correlation {correlation:.3}, {points} control points, min det {:.3}",
        error.mean_mm,
        100.0 * error.within_2_voxels,
        100.0 * error.within_4_voxels,
        result.min_jacobian
    );
    Scored {
        error,
        initial_error,
        correlation,
        result,
        labels: [source.labels, target.labels],
    }
}

/// The small phantom registered on the CPU with the defaults at 30° or 60°, once per test
/// binary: the 60° test, the inverse's and the whole-pipeline agreement read the same runs.
fn cpu_with_defaults(flexion: f64) -> &'static Scored {
    const FLEXIONS: [f64; 2] = [30.0, 60.0];
    static RUNS: OnceLock<[Scored; 2]> = OnceLock::new();
    let runs = RUNS.get_or_init(|| {
        FLEXIONS.map(|flexion| {
            let options = RegisterOptions::default();
            let cpu = &posereg::cpu::CpuBackend;
            register_and_score(cpu, PhantomSize::Small, flexion, &options, "cpu")
        })
    });
    &runs[FLEXIONS.iter().position(|&f| f == flexion).unwrap()]
}

/// What [`register_and_score`] measured.
struct Scored {
    /// The final field against the truth.
    error: FieldError,
    /// The initial field against the truth (with the articulated initialisation).
    initial_error: Option<FieldError>,
    /// Correlation of the warped source with the target.
    correlation: f64,
    result: Registration,
    /// The source's labels and the target's true labels.
    labels: [Labels; 2],
}

/// The paper's first experiment (10°, no initialisation) with the paper's method: the adaptive
/// stage alone, no dense refinement.
fn ten_degrees_without_initialisation<B: Backend>(backend: &B, size: PhantomSize, name: &str) {
    let mut options = RegisterOptions {
        initialise: false,
        ..Default::default()
    };
    options.dense.enabled = false;
    let Scored {
        error: e,
        correlation: r,
        result,
        ..
    } = register_and_score(backend, size, 10.0, &options, name);
    assert!(e.mean_mm <= 3.2, "mean error {} mm", e.mean_mm);
    assert!(r >= 0.95, "correlation {r}");
    assert!(
        e.within_2_voxels >= 0.87,
        "within 2 voxels {}",
        e.within_2_voxels
    );
    assert!(
        e.within_4_voxels >= 0.998,
        "within 4 voxels {}",
        e.within_4_voxels
    );
    assert!(
        result.min_jacobian > 0.0,
        "the field folds (min det {})",
        result.min_jacobian
    );
}

#[test]
fn paper_experiment_one_on_the_cpu() {
    for size in [PhantomSize::Quarter, PhantomSize::Small] {
        ten_degrees_without_initialisation(&posereg::cpu::CpuBackend, size, "cpu");
    }
}

/// A target whose contrast differs from the source's (a gamma curve on its intensities and a
/// shading ramp across it, as between scans from different days or coils): the 10° pair without
/// the initialisation, registered on `backend` with each of `similarities` at every level of
/// the adaptive stage (no dense refinement); the field errors.
fn ten_degrees_with_other_contrast<B: Backend, const N: usize>(
    backend: &B,
    similarities: [Similarity; N],
    name: &str,
) -> [FieldError; N] {
    let (source, mut target) = pair(PhantomSize::Quarter, 10.0);
    let nx = target.image.grid.dims[0];
    for (n, v) in target.image.data.iter_mut().enumerate() {
        let shading = 0.7 + 0.6 * (n % nx) as f32 / nx as f32;
        *v = shading * 40.0 * (v.max(0.0) / 40.0).powf(0.5);
    }
    let mask = evaluation_mask(&source, &target);
    similarities.map(|similarity| {
        let mut options = RegisterOptions {
            initialise: false,
            ..Default::default()
        };
        options.adaptive.similarity = PerLevel::all(similarity);
        // The adaptive stage's image term alone: the dense refinement's LNCC would rescue the
        // SSD run and hide the difference.
        options.dense.enabled = false;
        let inputs = Inputs::new(&source.image, &source.labels, &target.image);
        let result = register(backend, inputs, &options, &Silent).unwrap();
        let error = field_error(&result.field, &target.truth_field, |n| mask[n]).unwrap();
        eprintln!("{name} {similarity}: mean {:.2} mm", error.mean_mm);
        error
    })
}

/// Local correlation holds the paper's bound for this pair (≤ 3.2 mm, which the SSD meets when
/// the contrast is the same) across the contrast change; the SSD, even after its smooth gain,
/// does far worse (measured: 2.57 against 37.4 mm; the gain is matched only from the second
/// level on without the initialisation, and a gamma curve is not a gain).
///
/// The same on the GPU path (lavapipe in CI), its error near the CPU's: the LNCC kernels give
/// the same bits on both backends (tests/parity.rs), the RBF's do not (see
/// `the_whole_pipeline_agrees_on_both_backends`), and without the initialisation L-BFGS carries
/// that difference further (measured: 2.65 against 2.57 mm); the bound is that test's field
/// bound at 60°.
#[test]
fn local_correlation_registers_across_a_contrast_change_on_both_backends() {
    let [ssd, lncc] = ten_degrees_with_other_contrast(
        &posereg::cpu::CpuBackend,
        [Similarity::Ssd, Similarity::Lncc],
        "cpu",
    );
    assert!(
        lncc.mean_mm <= 3.2,
        "local correlation: {} mm",
        lncc.mean_mm
    );
    assert!(
        lncc.mean_mm < 0.5 * ssd.mean_mm,
        "local correlation {} mm against the SSD's {} mm",
        lncc.mean_mm,
        ssd.mean_mm
    );
    let Some(gpu) = common::gpu() else { return };
    let [got] = ten_degrees_with_other_contrast(gpu, [Similarity::Lncc], "gpu");
    assert!(got.mean_mm <= 3.2, "local correlation: {} mm", got.mean_mm);
    assert!(
        (got.mean_mm - lncc.mean_mm).abs() <= 0.15,
        "gpu {} mm, cpu {} mm",
        got.mean_mm,
        lncc.mean_mm
    );
}

/// 60° with the articulated initialisation, on the CPU: issue 5's bound (≤ 1.5 mm; 0.89 mm
/// measured at this size with the defaults, the dense refinement included, 0.90 without it;
/// 2026-12-07), and the adaptive stage must improve on the
/// initial field it starts from (1.70 mm here) — before the membrane energy it made it worse at
/// 30° (0.75 → 1.26 mm at the half size).
#[test]
fn sixty_degrees_with_the_initialisation_on_the_cpu() {
    let Scored {
        error: e,
        initial_error,
        correlation: r,
        ..
    } = cpu_with_defaults(60.0);
    let before = initial_error
        .as_ref()
        .expect("registered with the initialisation");
    assert!(e.mean_mm <= 1.5, "mean error {} mm", e.mean_mm);
    assert!(
        e.mean_mm < before.mean_mm,
        "the adaptive stage did not improve on the initial field: {} -> {} mm",
        before.mean_mm,
        e.mean_mm
    );
    assert!(
        e.within_4_voxels >= 0.99,
        "within 4 voxels {}",
        e.within_4_voxels
    );
    assert!(*r >= 0.9, "correlation {r}");
}

/// The bones of the final field move exactly by the motions the registration reports: the
/// adaptive warp is held off them (`bone_margin_mm`). Checked on the target's bone voxels
/// whose six neighbours lie in the same bone (a registration's bone edge may differ from the
/// truth's by a voxel) and whose source point lies in that bone of the source's labels (beyond
/// the source's field of view no label says it is bone, and the initial field blends it as
/// tissue). Without the holding the warp bends the femur here by up to 0.87 mm; with it the
/// largest departure is float rounding.
#[test]
fn bones_of_the_final_field_move_exactly_rigidly() {
    let Scored {
        result,
        labels: [source_labels, target_labels],
        ..
    } = cpu_with_defaults(60.0);
    let init = result
        .init
        .as_ref()
        .expect("registered with the initialisation");
    let grid = &result.field.grid;
    for (code, motion) in &init.motions {
        let to_source = motion.try_inverse().expect("a rigid motion");
        let rigid = |n: usize| to_source.transform_point(&grid.world_of(n).into()).coords;
        let interior: Vec<usize> = interior_voxels(target_labels, *code)
            .into_iter()
            .filter(|&n| label_at(source_labels, rigid(n)) == Some(*code))
            .collect();
        assert!(
            interior.len() > 100,
            "bone {code}: {} voxels",
            interior.len()
        );
        let worst = interior.iter().fold(0.0f64, |worst, &n| {
            let u = result.field.data[n];
            let reached = grid.world_of(n) + Vector3::new(u[0] as f64, u[1] as f64, u[2] as f64);
            worst.max((reached - rigid(n)).norm())
        });
        assert!(
            worst < 0.01,
            "bone {code}: {worst} mm from its rigid motion"
        );
    }
}

/// The label of the voxel of `labels` nearest the world point `x`; none outside its grid.
fn label_at(labels: &Labels, x: Vector3<f64>) -> Option<u16> {
    let grid = &labels.grid;
    let [i, j, k] = {
        let v = grid.world_to_voxel_affine() * x.push(1.0);
        [v.x, v.y, v.z].map(|c| c.round() as usize)
    };
    grid.contains(&x).then(|| labels.data[grid.index(i, j, k)])
}

/// Voxels labelled `code` whose six neighbours are labelled `code` too.
fn interior_voxels(labels: &Labels, code: u16) -> Vec<usize> {
    let d = labels.grid.dims;
    let at = |i: usize, j: usize, k: usize| labels.data[labels.grid.index(i, j, k)];
    let mut inside = Vec::new();
    for k in 1..d[2] - 1 {
        for j in 1..d[1] - 1 {
            for i in 1..d[0] - 1 {
                let around = [
                    at(i, j, k),
                    at(i - 1, j, k),
                    at(i + 1, j, k),
                    at(i, j - 1, k),
                    at(i, j + 1, k),
                    at(i, j, k - 1),
                    at(i, j, k + 1),
                ];
                if around.iter().all(|&l| l == code) {
                    inside.push(labels.grid.index(i, j, k));
                }
            }
        }
    }
    inside
}

/// 90° with the articulated initialisation, on the CPU: the warp composed with the initial
/// field, which is sharply compressed behind the knee, folds it there (144 voxels with
/// det J ≤ 0.05 measured, 2026-12-07); the unfolding lifts them but for a voxel or two pinned
/// between bones, without costing accuracy (1.59 mm with the defaults).
#[test]
fn ninety_degrees_leaves_the_field_all_but_unfolded() {
    let Scored {
        error: e,
        initial_error,
        result,
        ..
    } = register_and_score(
        &posereg::cpu::CpuBackend,
        PhantomSize::Small,
        90.0,
        &RegisterOptions::default(),
        "90°",
    );
    let unfolding = &result.unfolding;
    eprintln!("unfolding: {unfolding:?}");
    assert!(
        unfolding.folded_before > 50,
        "the composed field did not fold here: the test no longer exercises the unfolding"
    );
    let folded = (result.folded_share * result.field.data.len() as f64).round();
    assert!(folded <= 2.0, "{folded} voxels still fold");
    assert!(
        unfolding.folded_after * 20 < unfolding.folded_before,
        "{unfolding:?}"
    );
    let before = initial_error.expect("registered with the initialisation");
    assert!(
        e.mean_mm < before.mean_mm,
        "{} -> {} mm",
        before.mean_mm,
        e.mean_mm
    );
}

/// At the paper's size only: lavapipe takes a minute and a half more for the small size, which
/// the CPU test covers, and the whole-pipeline test below holds the GPU path to the CPU's there.
#[test]
fn paper_experiment_one_on_the_gpu() {
    let Some(gpu) = common::gpu() else { return };
    ten_degrees_without_initialisation(gpu, PhantomSize::Quarter, "gpu");
}

/// The whole pipeline on the GPU path (lavapipe in CI) against the CPU backend, on the small
/// phantom at 30° and 60° with the defaults: control points as many but for 2%, fields 0.05 mm
/// apart at most on average and errors 0.02 mm (issue 16's bounds), no further apart than the
/// CPU path is from itself when one bit of the target changes.
///
/// That floor was measured (2026-12-04, fourteenth session, with the lattice tied to the cells
/// and threshold 8x8x4): the CPU path at 60° against itself with the last bit of every 7th,
/// 11th, 13th, 17th or 19th target voxel flipped gives fields 0.030–0.039 mm apart and 0–3
/// control points more (of 420, on `posereg phantom`'s small pair, whose noise differs from
/// this test's; 30° was not re-measured). With the sixth session's defaults it was 0.059–0.111 mm at 60°
/// (0.014–0.035 at 30°), and this test's bounds were 0.15 mm: L-BFGS, stopped by its iteration
/// cap on the finer levels before it converges, carries a last-bit difference to 10⁻³ of the
/// cost within a level, and a lattice of every voxel at the middle level gave it more to
/// carry. The backends' own difference is of that kind: nearly every kernel gives the same
/// bits on both (the parity tests), but lavapipe's f64 square root is not correctly rounded
/// (the RBF kernels), and a few f32 kernels whose arithmetic is only multiplies and adds
/// still differ in the last bit (jacobian, compose, rigid_gn, the dual-quaternion blend: most
/// likely multiply-adds fused by the driver). Measured here on lavapipe with the defaults (the
/// dense refinement on three levels included; 2026-12-07): fields 0.028 and 0.026 mm apart;
/// 359 / 359 and 398 / 397 points; errors 0.543 / 0.550 and 0.893 / 0.893 mm.
/// Both backends give the same bits run to run on one driver, so a run that passes on
/// lavapipe passes there again; another driver may round differently.
///
/// In one fresh-clone CI run the GPU side once gave 199 control points at 30° (fields 0.133 mm
/// apart): the tests of one binary share one GPU backend, and a download used to take the
/// pending work (other threads' kernels included) and submit it outside the lock, so another
/// thread's later submission could overtake it and read buffers not yet written. Since
/// gpu/resident.rs submits under the lock, the whole binary runs this test beside the others.
#[test]
fn the_whole_pipeline_agrees_on_both_backends() {
    let Some(gpu) = common::gpu() else { return };
    for (flexion, fields_mm, errors_mm) in [(30.0, 0.05, 0.02), (60.0, 0.05, 0.02)] {
        let options = RegisterOptions::default();
        let size = PhantomSize::Small;
        let cpu = cpu_with_defaults(flexion);
        let got = register_and_score(gpu, size, flexion, &options, "gpu");
        let (source, target) = pair(size, flexion);
        let mask = evaluation_mask(&source, &target);
        let (a, b) = (&cpu.result.field.data, &got.result.field.data);
        let apart: Vec<f64> = (0..a.len())
            .filter(|&n| mask[n])
            .map(|n| {
                let d = (0..3).map(|c| (a[n][c] - b[n][c]) as f64);
                d.map(|d| d * d).sum::<f64>().sqrt()
            })
            .collect();
        let mean_apart = apart.iter().sum::<f64>() / apart.len() as f64;
        let points = |s: &Scored| s.result.adaptive.points.len();
        eprintln!(
            "{flexion}°: control points {} (cpu) {} (gpu); fields {mean_apart:.4} mm apart on average; errors {:.3} / {:.3} mm",
            points(cpu),
            points(&got),
            cpu.error.mean_mm,
            got.error.mean_mm
        );
        assert!(
            points(cpu).abs_diff(points(&got)) * 50 <= points(cpu),
            "{flexion}°: {} against {} control points",
            points(cpu),
            points(&got)
        );
        assert!(
            mean_apart <= fields_mm,
            "{flexion}°: fields {mean_apart} mm apart"
        );
        assert!(
            (cpu.error.mean_mm - got.error.mean_mm).abs() <= errors_mm,
            "{flexion}°: errors {} vs {} mm",
            cpu.error.mean_mm,
            got.error.mean_mm
        );
    }
}

/// `field` at world point `p`, trilinear over its grid; None outside its outer voxel centres.
/// The test's own interpolation: it shares nothing with the kernels.
fn field_at(field: &Field, p: &Vector3<f64>) -> Option<Vector3<f64>> {
    let q = field.grid.world_to_voxel_affine() * p.push(1.0);
    let d = field.grid.dims;
    let mut base = [0usize; 3];
    let mut t = [0.0f64; 3];
    for a in 0..3 {
        if q[a] < 0.0 || q[a] > (d[a] - 1) as f64 {
            return None;
        }
        base[a] = (q[a].floor() as usize).min(d[a] - 2);
        t[a] = q[a] - base[a] as f64;
    }
    let mut out = Vector3::zeros();
    for corner in 0..8 {
        let o = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
        let w: f64 = (0..3)
            .map(|a| if o[a] == 1 { t[a] } else { 1.0 - t[a] })
            .product();
        let n = field
            .grid
            .index(base[0] + o[0], base[1] + o[1], base[2] + o[2]);
        out += w * Vector3::from(field.data[n].map(f64::from));
    }
    Some(out)
}

/// The inverse field undoes the registration's field: a target point of the body carried to
/// the source by the field and back by the inverse lands within 0.1 mm of itself on average
/// (small phantom, 60°, CPU: the run the 60° test reads), and the report's round trip (source side) says as much.
#[test]
fn the_inverse_field_undoes_the_field_at_sixty_degrees() {
    let (source, target) = pair(PhantomSize::Small, 60.0);
    let result = &cpu_with_defaults(60.0).result;
    let mask = evaluation_mask(&source, &target);
    let body: Vec<usize> = (0..mask.len()).filter(|&n| mask[n]).collect();
    let errors: Vec<f64> = body
        .iter()
        .filter_map(|&n| {
            let x = target.image.grid.world_of(n);
            let y = x + Vector3::from(result.field.data[n].map(f64::from));
            field_at(&result.inverse, &y).map(|w| (y + w - x).norm())
        })
        .collect();
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let worst = errors.iter().cloned().fold(0.0, f64::max);
    let reached = errors.len() as f64 / body.len() as f64;
    let trip = &result.round_trip;
    eprintln!(
        "inverse after field: mean {mean:.5} mm, worst {worst:.3} mm over {:.1}% of the body; \
         report: mean {:.5}, max {:.3} mm, {:.2}% without a preimage, {:.4}% over 0.1 mm",
        100.0 * reached,
        trip.mean_mm,
        trip.max_mm,
        100.0 * trip.without_preimage,
        100.0 * trip.over_tenth_mm
    );
    assert!(mean <= 0.1, "mean round trip {mean} mm");
    assert!(
        reached >= 0.99,
        "only {reached} of the body lands in the source"
    );
    assert!(trip.mean_mm <= 0.1, "{trip:?}");
    assert_eq!(result.inverse.grid, source.image.grid);
}

/// `adaptive.finest_stride` 2 scores the finest level on an eighth of its voxels (the moving
/// image still sampled at full resolution): on the small phantom at 30° without the dense
/// refinement (which would amplify any difference in its start) the field ends as close to the
/// truth as with every voxel, within 0.05 mm (measured 2026-12-07: 0.54 mm with every voxel,
/// 0.56 with an eighth), and closer than the initial field.
#[test]
fn the_finest_level_on_every_other_voxel_ends_as_close_to_the_truth() {
    let cpu = &posereg::cpu::CpuBackend;
    let mut options = RegisterOptions::default();
    options.dense.enabled = false;
    let every = register_and_score(cpu, PhantomSize::Small, 30.0, &options, "stride 1");
    options.adaptive.finest_stride = 2;
    let sampled = register_and_score(cpu, PhantomSize::Small, 30.0, &options, "stride 2");
    let (e1, e2) = (every.error.mean_mm, sampled.error.mean_mm);
    let before = sampled.initial_error.as_ref().expect("initialised").mean_mm;
    assert!(
        (e2 - e1).abs() <= 0.05,
        "{e1} mm with every voxel, {e2} with an eighth"
    );
    assert!(
        e2 < before,
        "the finest level did not improve on {before} mm: {e2}"
    );
}
