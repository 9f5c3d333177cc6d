//! Articulated initialisation on noisy phantoms with known truth, on both backends.

mod common;

use posereg::progress::Silent;

use common::{host_determinant, resample_volume};
use posereg::abi::Interpolation;
use posereg::cpu::CpuBackend;
use posereg::images::metric::{correlation, dice};
use posereg::init::articulated::{
    initialise_volumes, rigid_field, InitOptions, InitialVolumes, Initialisation, Start,
};
use posereg::labels as label;
use posereg::phantom::{generate, Phantom, PhantomSize, PhantomSpec};
use posereg::{Backend, Image};
use std::sync::OnceLock;

/// Half-size phantoms with 2% Rician noise (seeded differently per pose). The bias field is
/// left off here: it is fixed to the scanner, so a bone that moves through it changes
/// brightness, which at 2.5 mm voxels costs the small bones a few tenths of a degree; the
/// paper-resolution test below keeps it on.
fn phantom(degrees: f64, seed: u64) -> Phantom {
    generate(&PhantomSpec {
        size: PhantomSize::Half,
        flexion_degrees: degrees,
        seed,
        bias: 0.0,
        ..Default::default()
    })
    .unwrap()
}

fn straight() -> &'static Phantom {
    static S: OnceLock<Phantom> = OnceLock::new();
    S.get_or_init(|| phantom(0.0, 100))
}

const ANGLES: [f64; 4] = [0.0, 30.0, 60.0, 90.0];

fn bent(degrees: f64) -> &'static Phantom {
    static B: OnceLock<Vec<Phantom>> = OnceLock::new();
    let all = B.get_or_init(|| ANGLES.iter().map(|&a| phantom(a, 7 + a as u64)).collect());
    &all[ANGLES.iter().position(|&a| a == degrees).unwrap()]
}

fn centroid(labels: &posereg::Labels, code: u16) -> nalgebra::Vector4<f64> {
    let (mut sum, mut n) = (nalgebra::Vector3::zeros(), 0.0);
    for (i, &l) in labels.data.iter().enumerate() {
        if l == code {
            sum += labels.grid.world_of(i);
            n += 1.0;
        }
    }
    (sum / n).push(1.0)
}

/// Dice of each bone, straight → target through the initial field, against (1) the target's
/// label map and (2) the straight bone moved by the truth field the same way. Indicators are
/// pulled trilinearly and kept where >= 0.5 (the partial-volume boundary), over the target
/// voxels the straight scan saw. (2) isolates the initialisation's error from the half-voxel
/// uncertainty of centre-sampled labels, which alone costs thin bones a few % at 2.5 mm.
fn bone_overlap<B: Backend>(
    backend: &B,
    s: &Phantom,
    b: &Phantom,
    images: &InitialVolumes,
) -> Vec<(u16, f64, f64)> {
    let pull = |v: &posereg::Volume, f: &posereg::Field| {
        resample_volume(backend, v, f, 0.0, Interpolation::Linear)
            .unwrap()
            .data
    };
    let all: posereg::Volume = Image::filled(s.labels.grid.clone(), 1.0);
    let seen: Vec<bool> = pull(&all, &images.field)
        .iter()
        .map(|&v| v >= 1.0)
        .collect();
    [label::FEMUR, label::TIBIA, label::PATELLA, label::FIBULA]
        .into_iter()
        .map(|code| {
            let indicator: posereg::Volume = Image {
                grid: s.labels.grid.clone(),
                data: s
                    .labels
                    .data
                    .iter()
                    .map(|&l| (l == code) as u8 as f32)
                    .collect(),
            };
            let inside = |pulled: Vec<f32>| -> Vec<bool> {
                pulled
                    .iter()
                    .zip(&seen)
                    .map(|(v, s)| *s && *v >= 0.5)
                    .collect()
            };
            let moved = inside(pull(&indicator, &images.field));
            let by_truth = inside(pull(&indicator, &b.truth_field));
            let labels: Vec<bool> = b
                .labels
                .data
                .iter()
                .zip(&seen)
                .map(|(l, s)| *s && *l == code)
                .collect();
            (
                code,
                dice(&moved, &labels, true),
                dice(&moved, &by_truth, true),
            )
        })
        .collect()
}

/// Checks everything the issue asks of one initialisation; returns a one-line summary.
fn check<B: Backend>(
    backend: &B,
    name: &str,
    s: &Phantom,
    b: &Phantom,
    (init, images): &(Initialisation, InitialVolumes),
    check_label_dice: bool,
) -> String {
    let degrees = b.truth.extra["flexion_axis"]["degrees"].as_f64().unwrap();
    let mut summary = format!("{name} {degrees}°:");
    for (code, estimate) in &init.motions {
        let truth = b
            .truth
            .bones
            .iter()
            .find(|t| t.label == *code)
            .unwrap()
            .affine();
        let c = centroid(&s.labels, *code);
        let shift = (estimate * c - truth * c).xyz().norm();
        let relative =
            estimate.fixed_view::<3, 3>(0, 0).transpose() * truth.fixed_view::<3, 3>(0, 0);
        let angle = ((relative.trace() - 1.0) / 2.0)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        summary += &format!(" {code}: {angle:.2}° {shift:.2} mm;");
        assert!(
            angle <= 0.5 && shift <= 0.5,
            "{summary} bone {code} misses: {angle}° {shift} mm"
        );
    }
    // Bones of the initialised source overlap the target bones.
    for (code, against_labels, against_truth) in bone_overlap(backend, s, b, images) {
        summary += &format!(" dice{code} {against_labels:.3} (vs truth-moved {against_truth:.3})");
        // Every bone, the patella included at 60° and 90° where the blend folds beside it (0.973
        // and 0.966 measured: the fold repair no longer smooths soft tissue into the bone).
        assert!(
            against_truth >= 0.95,
            "{summary}: bone {code} overlaps the truth-moved bone by {against_truth}"
        );
        if check_label_dice {
            assert!(
                against_labels >= 0.95,
                "{summary}: Dice of bone {code} is {against_labels}"
            );
        }
    }
    // The initial field does not fold in the soft tissue. The blend itself does beyond about
    // 30° (beside the patella, behind the knee); the repair smooths most of it away and pushes
    // what is pinned by a bone until det J > 0.05 (src/images/fold_repair.rs).
    let det = host_determinant(backend, &images.field).unwrap();
    let soft: Vec<f32> = det
        .iter()
        .zip(&b.labels.data)
        .filter(|(_, &l)| l == label::SOFT_TISSUE)
        .map(|(d, _)| *d)
        .collect();
    let folded = soft.iter().filter(|&&d| d <= 0.0).count();
    let least = soft.iter().cloned().fold(f32::INFINITY, f32::min);
    let repair = &init.repair;
    summary += &format!(
        " folds of the blend {} -> {} (min det in soft tissue {least:.3})",
        repair.folded_before, repair.folded_after
    );
    assert_eq!(
        folded, 0,
        "{summary}: the initial field folds in soft tissue"
    );
    // Closer to the target than aligning the femur alone.
    let body = |n: usize| b.labels.data[n] != label::OUTSIDE;
    let femur = init.motions.iter().find(|m| m.0 == label::FEMUR).unwrap().1;
    let femur_only = resample_volume(
        backend,
        &s.image,
        &rigid_field(&femur, &b.image.grid).unwrap(),
        0.0,
        Interpolation::Linear,
    )
    .unwrap();
    let r_femur = correlation(&femur_only.data, &b.image.data, body);
    let r_init = correlation(&images.initialised.data, &b.image.data, body);
    summary += &format!(" corr femur-only {r_femur:.3} init {r_init:.3}");
    if degrees > 0.0 {
        assert!(r_init > r_femur, "{summary}");
    }
    summary
}

fn run_at<B: Backend>(backend: &B, name: &str, angles: &[f64]) {
    for &degrees in angles {
        let init = initialise_volumes(
            backend,
            &straight().image,
            &straight().labels,
            &bent(degrees).image,
            &InitOptions::default(),
            None,
            &Silent,
        )
        .unwrap();
        eprintln!(
            "{}",
            check(backend, name, straight(), bent(degrees), &init, false)
        );
    }
}

#[test]
fn recovers_every_bone_from_0_to_90_degrees_on_the_cpu() {
    run_at(&CpuBackend, "cpu", &ANGLES);
}

/// On lavapipe at the two angles where the blend folds beside the patella and behind the knee
/// and the fold repair runs (40 s an angle there; the CPU test covers the others).
#[test]
fn recovers_every_bone_at_60_and_90_degrees_on_the_gpu() {
    let Some(gpu) = common::gpu() else { return };
    run_at(gpu, "gpu", &[60.0, 90.0]);
}

#[test]
fn at_the_papers_resolution_bones_overlap_the_target_labels() {
    // 136×256×256 at 1.25 mm, 90° (the sweep above covers 60° at 2.5 mm; this size costs a
    // minute an angle), noise and bias on: Dice against the target's own label map (at 2.5 mm
    // the patella, 8 voxels thick, falls to 0.94-0.95 however well it is placed: its
    // truth-moved Dice above is ≥ 0.97).
    let paper = |degrees: f64, seed: u64| {
        generate(&PhantomSpec {
            size: PhantomSize::Paper,
            flexion_degrees: degrees,
            seed,
            ..Default::default()
        })
        .unwrap()
    };
    let s = paper(0.0, 100);
    let degrees = 90.0;
    let b = paper(degrees, 7 + degrees as u64);
    let init = initialise_volumes(
        &CpuBackend,
        &s.image,
        &s.labels,
        &b.image,
        &InitOptions::default(),
        None,
        &Silent,
    )
    .unwrap();
    eprintln!("{}", check(&CpuBackend, "cpu paper", &s, &b, &init, true));
}

#[test]
fn given_transforms_skip_the_rigid_stage() {
    let b = bent(60.0);
    let (init, _) = initialise_volumes(
        &CpuBackend,
        &straight().image,
        &straight().labels,
        &b.image,
        &InitOptions::default(),
        Some(Start::Given(&b.truth)),
        &Silent,
    )
    .unwrap();
    assert!(init.reports.is_empty());
    for (code, m) in &init.motions {
        let truth = b
            .truth
            .bones
            .iter()
            .find(|t| t.label == *code)
            .unwrap()
            .affine();
        assert_eq!(*m, truth);
    }
}

/// On the project's phantom at 60° (its own truth: the anterior thigh stays with the femur
/// while the patella turns), the reach the initialisation keeps gives an initial field within
/// 3% of the truest candidate's; the same is asked on a truth from outside the project in
/// tests/independent_pairs.rs, where another limit is the truest.
#[test]
fn the_reach_kept_is_the_truest_on_the_phantom() {
    let b = bent(60.0);
    let body: Vec<bool> = b.labels.data.iter().map(|&l| l > 0).collect();
    let s = straight();
    let (fixed, (limit, error)) = common::initial_error_by_reach(
        (&s.image, &s.labels, &b.image),
        &b.truth,
        &b.truth_field,
        &body,
    );
    let best = fixed.iter().map(|f| f.1).fold(f64::INFINITY, f64::min);
    assert!(
        error <= 1.03 * best,
        "kept {limit}: {error:.3} mm; fixed limits {fixed:?}"
    );
}

#[test]
fn missing_bones_are_refused() {
    let s = straight();
    let options = InitOptions {
        bones: vec![label::FEMUR, 9],
        ..Default::default()
    };
    let err = initialise_volumes(
        &CpuBackend,
        &s.image,
        &s.labels,
        &bent(30.0).image,
        &options,
        None,
        &Silent,
    )
    .err()
    .unwrap();
    assert!(err.to_string().contains("bone label 9"), "{err}");
}
