//! Registration of pairs made by scripts/make_pair.py, which shares no code or motion model
//! with posereg (numpy and SimpleITK; its own flexion axis; a polyrigid flow; bones exactly
//! rigid). The truth is the generator's. Needs python3 with SimpleITK and numpy: skipped
//! without them, a failure with REQUIRE_INTEROP=1 (CI sets it).

mod common;

use posereg::cpu::CpuBackend;
use posereg::init::articulated::{initialise_volumes, InitOptions, Initialisation};
use posereg::io::field::load_field;
use posereg::io::nifti::{load_labels, load_volume};
use posereg::io::transform::BoneTransforms;
use posereg::joints::confidence::Decision;
use posereg::joints::joint::degrees_between;
use posereg::labels as label;
use posereg::progress::Silent;
use posereg::Backend;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs scripts/make_pair.py with `args`; false when python3 or its packages are missing and
/// REQUIRE_INTEROP is not set.
fn make_pair(args: &[&str]) -> bool {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/make_pair.py");
    let run = Command::new("python3").arg(&script).args(args).output();
    match run {
        Ok(out) if out.status.success() => true,
        outcome => {
            let why = match outcome {
                Ok(out) => String::from_utf8_lossy(&out.stderr).into_owned(),
                Err(e) => e.to_string(),
            };
            if std::env::var("REQUIRE_INTEROP").as_deref() == Ok("1") {
                panic!("REQUIRE_INTEROP=1 but make_pair.py failed: {why}");
            }
            eprintln!("skipped: make_pair.py failed: {why}");
            false
        }
    }
}

/// posereg's small phantom, straight, written in `dir`: its image and its labels.
fn small_phantom(dir: &Path) -> (PathBuf, PathBuf) {
    let straight = dir.join("straight");
    let made = common::posereg(&[
        "phantom",
        "--quiet",
        "--device",
        "cpu",
        "--size",
        "small",
        "-o",
        straight.to_str().unwrap(),
    ]);
    assert!(made.status.success(), "{made:?}");
    (
        straight.join("image.nii.gz"),
        straight.join("labels.nii.gz"),
    )
}

fn initialise<B: Backend>(backend: &B, pair: &Path) -> Initialisation {
    let source = load_volume(&pair.join("source.nii.gz")).unwrap();
    let labels = load_labels(&pair.join("source_labels.nii.gz")).unwrap();
    let target = load_volume(&pair.join("target.nii.gz")).unwrap();
    let options = InitOptions::default();
    initialise_volumes(backend, &source, &labels, &target, &options, None, &Silent)
        .unwrap()
        .0
}

fn motion(init: &Initialisation, code: u16) -> posereg::volume::Affine {
    init.motions.iter().find(|m| m.0 == code).unwrap().1
}

/// The fibula case of issue 17: the target's field of view keeps only part of the fibula (and
/// of the tibia), so the fibula's own cost is ambiguous. It must follow the tibia, within 2°,
/// and the report must say so, on both backends; the femur and tibia stay within 1° of the
/// generator's truth. The labelled scan is posereg's small phantom (the motion, the soft
/// tissue and the cut are the generator's).
#[test]
fn a_barely_seen_fibula_follows_the_tibia_on_both_backends() {
    let dir = tempfile::tempdir().unwrap();
    let (image, labels) = small_phantom(dir.path());
    let pair = dir.path().join("pair");
    if !make_pair(&[
        "--image",
        image.to_str().unwrap(),
        "--labels",
        labels.to_str().unwrap(),
        "--degrees",
        "30",
        "--spacing",
        "0",
        "--target-keep",
        "2",
        "0.3",
        "1",
        "--seed",
        "3",
        "-o",
        pair.to_str().unwrap(),
    ]) {
        return;
    }
    let truth = BoneTransforms::load(&pair.join("truth.json")).unwrap();
    let true_motion = |code| {
        truth
            .bones
            .iter()
            .find(|b| b.label == code)
            .unwrap()
            .affine()
    };
    let mut runs = vec![("cpu", initialise(&CpuBackend, &pair))];
    if let Some(gpu) = common::gpu() {
        runs.push(("gpu", initialise(gpu, &pair)));
    }
    for (device, init) in &runs {
        let fibula = init
            .reports
            .iter()
            .find(|r| r.label == label::FIBULA)
            .unwrap();
        let c = &fibula.confidence;
        assert_eq!(c.decision, Decision::FollowedParent, "{device}: {c:?}");
        assert!(
            c.seen < 0.5,
            "{device}: the cut left {:.2} of the fibula",
            c.seen
        );
        let apart = degrees_between(&motion(init, label::TIBIA), &motion(init, label::FIBULA));
        assert!(apart < 2.0, "{device}: fibula {apart:.2}° from the tibia");
        for code in [label::FEMUR, label::TIBIA] {
            let off = degrees_between(&true_motion(code), &motion(init, code));
            assert!(off < 1.0, "{device}: bone {code} {off:.2}° from the truth");
        }
    }
}

/// On the small phantom bent 45° by the generator (whose tissue follows the nearest bone
/// whatever its size), the reach the initialisation keeps gives an initial field within 3% of
/// the truest candidate's, measured against the generator's truth (tests/articulated.rs asks
/// the same on the project's phantom, where another limit is the truest).
#[test]
fn the_reach_kept_is_the_truest_on_an_independent_pair() {
    let dir = tempfile::tempdir().unwrap();
    let (image, labels) = small_phantom(dir.path());
    let pair = dir.path().join("pair");
    let args = ["--degrees", "45", "--spacing", "0", "--seed", "3", "-o"];
    let image_args = [
        "--image",
        image.to_str().unwrap(),
        "--labels",
        labels.to_str().unwrap(),
    ];
    if !make_pair(&[&image_args[..], &args, &[pair.to_str().unwrap()]].concat()) {
        return;
    }
    let load = |name: &str| load_volume(&pair.join(name)).unwrap();
    let body: Vec<bool> = load_labels(&pair.join("target_labels.nii.gz"))
        .unwrap()
        .data
        .iter()
        .map(|&l| l > 0)
        .collect();
    let (fixed, (limit, error)) = common::initial_error_by_reach(
        (
            &load("source.nii.gz"),
            &load_labels(&pair.join("source_labels.nii.gz")).unwrap(),
            &load("target.nii.gz"),
        ),
        &BoneTransforms::load(&pair.join("truth.json")).unwrap(),
        &load_field(&pair.join("truth_field.nii.gz")).unwrap(),
        &body,
    );
    let best = fixed.iter().map(|f| f.1).fold(f64::INFINITY, f64::min);
    assert!(
        error <= 1.03 * best,
        "kept {limit}: {error:.3} mm; fixed limits {fixed:?}"
    );
}

/// `posereg register` on `pair` with `--device device`, scored by scripts/score_pair.py.
fn register_and_score(pair: &Path, out: &Path, device: &str) -> serde_json::Value {
    register_and_score_with(pair, out, device, &[])
}

/// [`register_and_score`] with `extra` arguments for `posereg register`.
fn register_and_score_with(
    pair: &Path,
    out: &Path,
    device: &str,
    extra: &[&str],
) -> serde_json::Value {
    let arg = |name: &str| pair.join(name).to_str().unwrap().to_string();
    let inputs = [
        "--source",
        &arg("source.nii.gz"),
        "--source-labels",
        &arg("source_labels.nii.gz"),
        "--target",
        &arg("target.nii.gz"),
    ];
    let run = common::posereg(
        &[
            &["register", "--quiet", "--device", device][..],
            &inputs,
            extra,
            &["-o", out.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(run.status.success(), "{device}: {run:?}");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/score_pair.py");
    let scored = Command::new("python3")
        .arg(script)
        .arg(pair)
        .arg(out.join("field.nii.gz"))
        .arg("--bones")
        .arg(out.join("transform.json"))
        .arg("--json")
        .output()
        .unwrap();
    assert!(scored.status.success(), "{scored:?}");
    serde_json::from_slice(&scored.stdout).unwrap()
}

/// The devices to register on: the CPU, and the GPU where there is one (REQUIRE_GPU=1 makes
/// its absence a failure).
fn devices() -> Vec<&'static str> {
    match common::gpu() {
        Some(_) => vec!["cpu", "gpu"],
        None => vec!["cpu"],
    }
}

/// Each bone's (rotation error °, translation error at its centroid mm) from a score.
fn bone_errors(score: &serde_json::Value) -> Vec<(String, f64, f64)> {
    let bones = score["bones"].as_object().unwrap();
    bones
        .iter()
        .map(|(name, e)| {
            let get = |k: &str| e[k].as_f64().unwrap();
            (name.clone(), get("degrees"), get("mm"))
        })
        .collect()
}

/// Issue 17's bar on one of its pairs, at its smaller size: the shared real knee at 2 mm bent
/// 20° by the generator, registered with the defaults on both backends: every bone within 1°
/// and 0.5 mm, the mean field error over the body at most 1.0 mm, no fold in the body.
/// ../shared/data is beside the checkout on development machines; without it the test says
/// so and stops (the phantom test below always runs).
#[test]
fn the_real_knee_bent_20_degrees_independently_meets_the_bar_on_both_backends() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/knee-dess");
    if !data.exists() {
        eprintln!("skipped: {} not present", data.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let pair = dir.path().join("pair");
    let (image, labels) = (data.join("image.nii.gz"), data.join("labels.nii.gz"));
    let made = make_pair(&[
        "--image",
        image.to_str().unwrap(),
        "--labels",
        labels.to_str().unwrap(),
        "--degrees",
        "20",
        "--spacing",
        "2",
        "--seed",
        "11",
        "-o",
        pair.to_str().unwrap(),
    ]);
    if !made {
        return;
    }
    let mut on_cpu = None;
    for device in devices() {
        let score = register_and_score(&pair, &dir.path().join(device), device);
        for (bone, degrees, mm) in bone_errors(&score) {
            assert!(
                degrees <= 1.0 && mm <= 0.5,
                "{device}: {bone} {degrees:.2}° {mm:.2} mm"
            );
        }
        let mean = score["mean_mm"].as_f64().unwrap();
        assert!(mean <= 1.0, "{device}: mean field error {mean:.3} mm");
        assert_eq!(
            score["folded_share"].as_f64(),
            Some(0.0),
            "{device}: {score}"
        );
        on_cpu = on_cpu.or((device == "cpu").then_some(score));
    }
    // The dense refinement (on by default, three levels) against none on the same pair
    // (CPU): soft tissue closer, the bones' motions exactly as without it, still no fold.
    let dense = on_cpu.expect("the CPU registered");
    let plain = register_and_score_with(&pair, &dir.path().join("plain"), "cpu", &["--no-dense"]);
    let soft = |s: &serde_json::Value| s["soft_mm"].as_f64().unwrap();
    assert!(soft(&dense) < soft(&plain), "{plain} -> {dense}");
    assert_eq!(bone_errors(&dense), bone_errors(&plain));
}
