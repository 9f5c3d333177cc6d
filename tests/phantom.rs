//! The knee phantom: its truth is consistent with its images, it never folds, and it is
//! reproducible.

use posereg::abi::Interpolation;
use posereg::backend::resample_volume;
use posereg::cpu::CpuBackend;
use posereg::images::fold_repair::host_determinant;
use posereg::images::metric::{correlation, dice};
use posereg::phantom::anatomy::{label, BONES};
use posereg::phantom::{generate, Phantom, PhantomSize, PhantomSpec};
use posereg::volume::Image;
use rayon::prelude::*;
use std::sync::OnceLock;

fn clean(size: PhantomSize, flexion: f64) -> Phantom {
    generate(&PhantomSpec {
        size,
        flexion_degrees: flexion,
        bias: 0.0,
        noise: 0.0,
        seed: 1,
    })
    .unwrap()
}

/// Straight and 60°-bent noise-free phantoms at half size, made once per test binary.
fn pair() -> &'static (Phantom, Phantom) {
    static PAIR: OnceLock<(Phantom, Phantom)> = OnceLock::new();
    PAIR.get_or_init(|| {
        (
            clean(PhantomSize::Half, 0.0),
            clean(PhantomSize::Half, 60.0),
        )
    })
}

/// The 90°-bent noise-free phantom on the paper grid, made once per test binary. Only the paper
/// grid is finer than the flow's 2.5 mm lattice, so only there is the lattice interpolated.
fn paper_90() -> &'static Phantom {
    static BENT: OnceLock<Phantom> = OnceLock::new();
    BENT.get_or_init(|| clean(PhantomSize::Paper, 90.0))
}

/// The 60°-bent noise-free phantom on the paper grid, made once per test binary (the Dice and
/// the fold tests both read it).
fn paper_60() -> &'static Phantom {
    static BENT: OnceLock<Phantom> = OnceLock::new();
    BENT.get_or_init(|| clean(PhantomSize::Paper, 60.0))
}

/// Bent voxels whose straight-pose point lies inside the straight image (see
/// evaluate::seen_by_both).
fn seen_in_both(straight: &Phantom, bent: &Phantom, margin: f64) -> Vec<bool> {
    posereg::report::evaluate::seen_by_both(&bent.truth_field, &straight.image.grid, margin)
}

/// Voxels at least `margin` voxels from every face.
fn away_from_borders(dims: [usize; 3], margin: usize) -> impl Fn(usize) -> bool {
    move |n| {
        let ijk = [
            n % dims[0],
            (n / dims[0]) % dims[1],
            n / (dims[0] * dims[1]),
        ];
        (0..3).all(|a| ijk[a] >= margin && ijk[a] + margin < dims[a])
    }
}

#[test]
fn straight_image_through_the_truth_field_reproduces_the_bent_image() {
    let (straight, bent) = pair();
    let warped = resample_volume(
        &CpuBackend,
        &straight.image,
        &bent.truth_field,
        0.0,
        Interpolation::Linear,
    )
    .unwrap();
    let inner = away_from_borders(bent.image.grid.dims, 3);
    let seen = seen_in_both(straight, bent, 3.0);
    let inside_body = |n: usize| bent.labels.data[n] != label::OUTSIDE && inner(n) && seen[n];
    let r = correlation(&warped.data, &bent.image.data, inside_body);
    eprintln!("correlation inside the body: {r:.4}");
    assert!(r >= 0.99, "correlation {r}");
    // Without the truth field (identity), the two poses are far apart: the check has teeth.
    let r0 = correlation(&straight.image.data, &bent.image.data, inside_body);
    assert!(r0 < 0.8, "identity correlation {r0}");
}

#[test]
fn bone_labels_follow_the_truth_with_dice_at_least_098() {
    // Each straight bone's indicator is pulled into the bent pose through the truth field
    // (trilinear, kept where >= 0.5: the partial-volume boundary, not a nearest-voxel pick that
    // rounds a rotated boundary by up to half a voxel) and compared with the bent labels, over
    // the voxels both scans see. The same indicator pulled through the bone's exact rigid motion
    // (its truth.json matrix, applied to every voxel) measures what centre-sampled label maps
    // on two grids turned against each other allow at all.
    let straight = clean(PhantomSize::Paper, 0.0);
    let (straight, bent) = (&straight, paper_60());
    let seen = seen_in_both(straight, bent, 0.0);
    let grid = &bent.labels.grid;
    for (code, name) in BONES {
        let indicator: posereg::Volume = Image {
            grid: straight.labels.grid.clone(),
            data: straight
                .labels
                .data
                .iter()
                .map(|&l| (l == code) as u8 as f32)
                .collect(),
        };
        let truth: Vec<bool> = bent
            .labels
            .data
            .iter()
            .zip(&seen)
            .map(|(l, s)| *s && *l == code)
            .collect();
        let mapped_through = |field: &posereg::Field| -> Vec<bool> {
            let pulled =
                resample_volume(&CpuBackend, &indicator, field, 0.0, Interpolation::Linear)
                    .unwrap();
            pulled
                .data
                .iter()
                .zip(&seen)
                .map(|(v, s)| *s && *v >= 0.5)
                .collect()
        };
        let bone = bent.truth.bones.iter().find(|b| b.label == code).unwrap();
        let rigid = posereg::init::articulated::rigid_field(&bone.affine(), grid).unwrap();
        let (by_truth, by_motion) = (mapped_through(&bent.truth_field), mapped_through(&rigid));
        let missed = |mapped: &[bool]| {
            truth
                .iter()
                .zip(mapped)
                .filter(|(t, m)| **t && !**m)
                .count()
        };
        let d = dice(&by_truth, &truth, true);
        eprintln!(
            "{name}: Dice {d:.4} through the truth field, {:.4} through the exact motion; bone voxels missed {} and {}",
            dice(&by_motion, &truth, true),
            missed(&by_truth),
            missed(&by_motion)
        );
        // Bone voxels move exactly with their bone, so the truth misses the bent bone's voxels
        // that the exact motion misses, no more. (It differs in the tissue beside the bone,
        // which the bend stretches or squeezes: the patella gains 90 voxels there, 0.9737
        // against 0.9781.)
        assert!(
            missed(&by_truth) <= missed(&by_motion),
            "{name}: the truth field loses bone voxels its motion keeps"
        );
        // The thin bones (fibula: 14 mm across; patella: 20 mm thick) are 11-16 voxels across
        // at 1.25 mm: the half-voxel uncertainty of centre-sampled boundaries on two grids turned
        // 60° against each other holds even their exact motion to about 0.974. They are held to
        // 0.97, the long bones to the 0.98 the phantom issue asks.
        let bound = if code == label::PATELLA || code == label::FIBULA {
            0.97
        } else {
            0.98
        };
        assert!(d >= bound, "{name}: Dice {d} < {bound}");
    }
}

#[test]
fn truth_json_and_truth_field_agree_inside_every_bone() {
    // Inside bone j of the bent image the truth field must be exactly the inverse of bone j's
    // matrix in truth.json: the bones move rigidly and the two files say the same thing. On the
    // paper grid at 90°, where tissue slides fastest past the bones and the flow's lattice is
    // interpolated (interpolating it into the bones once moved 5% of the femur by up to 23 mm).
    let bent = paper_90();
    let g = &bent.labels.grid;
    for b in &bent.truth.bones {
        let inverse = b.affine().try_inverse().unwrap();
        let mut worst = 0.0f64;
        let mut count = 0;
        for n in (0..g.len()).filter(|&n| bent.labels.data[n] == b.label) {
            let w = g.world_of(n);
            let q = inverse * nalgebra::Vector4::new(w[0], w[1], w[2], 1.0);
            let u = bent.truth_field.data[n];
            let err = ((w[0] + u[0] as f64 - q.x).powi(2)
                + (w[1] + u[1] as f64 - q.y).powi(2)
                + (w[2] + u[2] as f64 - q.z).powi(2))
            .sqrt();
            worst = worst.max(err);
            count += 1;
        }
        eprintln!(
            "{}: {count} voxels, worst |field - matrix| {worst:.2e} mm",
            b.name
        );
        assert!(
            count > 100 && worst < 0.01,
            "{}: worst {worst} mm over {count} voxels",
            b.name
        );
    }
    // The femur stays; the shank turns by the flexion angle.
    let angle = |label: u16| {
        let m = bent
            .truth
            .bones
            .iter()
            .find(|b| b.label == label)
            .unwrap()
            .affine();
        ((m[(0, 0)] + m[(1, 1)] + m[(2, 2)] - 1.0) / 2.0)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    };
    assert!(angle(label::FEMUR).abs() < 1e-9);
    assert!((angle(label::TIBIA) - 90.0).abs() < 1e-6);
    assert!((angle(label::FIBULA) - 90.0).abs() < 1e-6);
}

#[test]
fn flexion_never_folds_inside_the_body() {
    // The flow is checked at every body voxel centre with ±0.1 mm differences (small grid);
    // the truth field as sampled on the grid with the Jacobian kernel, on the half and paper
    // grids at 60°, 90° and 120°. The flow turns faster than a voxel behind the condyles, and
    // the phantom pushes those voxels apart (phantom::unfolded).
    for degrees in [60.0, 90.0, 120.0] {
        let bent = clean(PhantomSize::Small, degrees);
        let flexion = posereg::phantom::flexion::Flexion::knee(degrees);
        let inverse = flexion.inverse_rotations(posereg::phantom::flexion::LATTICE_STEPS);
        let g = &bent.labels.grid;
        let min_continuous = body_voxels(&bent)
            .par_iter()
            .map(|&n| {
                let w = g.world_of(n);
                flexion.jacobian_determinant(
                    glam::Vec3::new(w[0] as f32, w[1] as f32, w[2] as f32),
                    0.1,
                    &inverse,
                )
            })
            .reduce(|| f32::INFINITY, f32::min);
        eprintln!("{degrees}°: min det of the map {min_continuous:.3}");
        assert!(
            min_continuous > 0.0,
            "{degrees}°: the map folds (det {min_continuous})"
        );
    }
    let grids = [
        (PhantomSize::Half, 60.0),
        (PhantomSize::Half, 90.0),
        (PhantomSize::Half, 120.0),
        (PhantomSize::Paper, 120.0),
    ];
    let check = |bent: &Phantom, name: String| {
        let det = host_determinant(&CpuBackend, &bent.truth_field).unwrap();
        let body = body_voxels(bent);
        let folded = body.iter().filter(|&&n| det[n] <= 0.0).count();
        eprintln!("{name}: {folded} of {} body voxels folded", body.len());
        assert_eq!(folded, 0, "{name}: grid voxels fold");
    };
    for (size, degrees) in grids {
        check(&clean(size, degrees), format!("{size:?} {degrees}°"));
    }
    check(paper_60(), "Paper 60°".into());
    check(paper_90(), "Paper 90°".into());
}

/// Flat indices of the voxels inside the body.
fn body_voxels(phantom: &Phantom) -> Vec<usize> {
    (0..phantom.labels.data.len())
        .filter(|&n| phantom.labels.data[n] != label::OUTSIDE)
        .collect()
}

#[test]
fn same_seed_gives_bit_identical_files() {
    let dir = tempfile::tempdir().unwrap();
    let bin = env!("CARGO_BIN_EXE_posereg");
    for run in ["a", "b"] {
        let status = std::process::Command::new(bin)
            .args([
                "phantom",
                "--size",
                "small",
                "--flexion",
                "30",
                "--seed",
                "7",
                "-o",
            ])
            .arg(dir.path().join(run))
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .status()
            .unwrap();
        assert!(status.success());
    }
    for file in [
        "image.nii.gz",
        "labels.nii.gz",
        "truth_field.nii.gz",
        "truth.json",
    ] {
        let a = std::fs::read(dir.path().join("a").join(file)).unwrap();
        let b = std::fs::read(dir.path().join("b").join(file)).unwrap();
        assert!(a == b, "{file} differs between runs");
    }
    // A different seed changes the noise.
    let other = generate(&PhantomSpec {
        size: PhantomSize::Small,
        flexion_degrees: 30.0,
        seed: 8,
        ..Default::default()
    })
    .unwrap();
    let first = posereg::io::nifti::load_volume(&dir.path().join("a/image.nii.gz")).unwrap();
    assert_ne!(first.data, other.image.data);
}

#[test]
fn phantom_has_every_label_and_plausible_intensities() {
    let (straight, _) = pair();
    for code in 0..=5u16 {
        assert!(straight.labels.data.contains(&code), "label {code} missing");
    }
    // Marrow is bright and cortex dark: the mean intensity inside bone is well above muscle's,
    // and the body is much brighter than the air around it.
    let mean = |l: u16| {
        let v: Vec<f32> = straight
            .image
            .data
            .iter()
            .zip(&straight.labels.data)
            .filter(|(_, &x)| x == l)
            .map(|(v, _)| *v)
            .collect();
        v.iter().sum::<f32>() / v.len() as f32
    };
    assert!(mean(label::FEMUR) > 500.0, "femur {}", mean(label::FEMUR));
    assert!(mean(label::OUTSIDE) < 50.0);
    assert!(mean(label::SOFT_TISSUE) > 200.0);
}

#[test]
fn bad_specs_are_refused() {
    for spec in [
        PhantomSpec {
            flexion_degrees: 130.0,
            ..Default::default()
        },
        PhantomSpec {
            flexion_degrees: -1.0,
            ..Default::default()
        },
        PhantomSpec {
            noise: f32::NAN,
            ..Default::default()
        },
        PhantomSpec {
            bias: 1.5,
            ..Default::default()
        },
    ] {
        assert!(generate(&spec).is_err());
    }
}
