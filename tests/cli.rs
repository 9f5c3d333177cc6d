//! The `posereg` binary: verbs, outputs, exit codes and error messages.

mod common;

use common::*;
use posereg::io::field::save_field;
use posereg::io::nifti::{load_volume, save_volume, DataType};
use posereg::Volume;
use std::path::{Path, PathBuf};
use std::process::Output;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn assert_fails_naming(out: &Output, name: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "expected failure, got success; stderr: {stderr}"
    );
    let last = stderr.lines().last().unwrap_or("");
    assert!(last.starts_with("posereg: error:"), "stderr: {stderr}");
    assert!(last.contains(name), "error does not name {name}: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn info_json_reports_the_affine_nibabel_reports() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let out = posereg(&["info", "--json", s(&data.join("oblique_nibabel.nii.gz"))]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let want: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(data.join("oblique_nibabel.json")).unwrap())
            .unwrap();
    for r in 0..4 {
        for c in 0..4 {
            let (g, w) = (
                got["affine"][r][c].as_f64().unwrap(),
                want["affine"][r][c].as_f64().unwrap(),
            );
            assert!((g - w).abs() < 1e-6, "affine[{r}][{c}]: {g} vs nibabel {w}");
        }
    }
    assert_eq!(got["dims"], serde_json::json!([5, 6, 7]));
    assert_eq!(got["orientation"], want["orientation"]);
    let text = posereg(&["info", s(&data.join("oblique_nibabel.nii.gz"))]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains("5 x 6 x 7") && text.contains("orientation"),
        "{text}"
    );
}

/// A smooth source on an oblique grid of `dims` and a zero field on the same grid, written
/// into `dir` as source.nii.gz and zero.nii.gz.
fn source_and_zero_field(dir: &Path, dims: [usize; 3], seed: u64) -> (Volume, PathBuf, PathBuf) {
    let grid = oblique_grid(dims);
    let source = smooth_volume(&grid, seed);
    let (src, field) = (dir.join("source.nii.gz"), dir.join("zero.nii.gz"));
    save_volume(&src, &source, DataType::F32).unwrap();
    save_field(&field, &constant_field(&grid, [0.0; 3])).unwrap();
    (source, src, field)
}

/// `posereg resample SRC --field FIELD --like SRC -o OUT` followed by `extra`.
fn resample_onto_itself(src: &Path, field: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "resample",
        s(src),
        "--field",
        s(field),
        "--like",
        s(src),
        "-o",
        s(out),
    ];
    args.extend_from_slice(extra);
    posereg(&args)
}

#[test]
fn resample_with_a_zero_field_reproduces_the_source_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let (source, src, field) = source_and_zero_field(dir.path(), [19, 14, 9], 31);
    let mut devices = vec!["cpu"];
    if gpu().is_some() {
        devices.push("gpu");
    }
    for device in devices {
        let out_path = dir.path().join(format!("out-{device}.nii.gz"));
        let out = resample_onto_itself(&src, &field, &out_path, &["--device", device]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let back = load_volume(&out_path).unwrap();
        assert_eq!(back.data, source.data, "--device {device}");
        let reread_source = load_volume(&src).unwrap();
        assert_eq!(back.grid, reread_source.grid);
    }
}

#[test]
fn threads_sets_the_cpu_backends_threads_and_refuses_zero() {
    let dir = tempfile::tempdir().unwrap();
    let (_, src, field) = source_and_zero_field(dir.path(), [9, 8, 7], 3);
    let out_path = dir.path().join("out.nii.gz");
    let run = |threads: &str| {
        resample_onto_itself(
            &src,
            &field,
            &out_path,
            &["--threads", threads, "--device", "cpu"],
        )
    };
    let one = run("1");
    let said = String::from_utf8_lossy(&one.stderr);
    assert!(
        one.status.success() && said.contains("cpu: 1 threads"),
        "{said}"
    );
    let zero = run("0");
    assert!(!zero.status.success());
    assert!(String::from_utf8_lossy(&zero.stderr).contains("--threads"));
}

#[test]
fn resample_errors_name_the_file_and_leave_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let grid = oblique_grid([6, 5, 4]);
    let src = dir.path().join("source.nii.gz");
    save_volume(&src, &smooth_volume(&grid, 1), DataType::F32).unwrap();
    let field = dir.path().join("field.nii.gz");
    save_field(&field, &constant_field(&grid, [1.0; 3])).unwrap();
    let other_grid = dir.path().join("other.nii.gz");
    save_volume(
        &other_grid,
        &smooth_volume(&oblique_grid([6, 5, 5]), 1),
        DataType::F32,
    )
    .unwrap();
    let truncated = dir.path().join("truncated.nii.gz");
    let bytes = std::fs::read(&src).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let out = dir.path().join("out.nii.gz");

    let run = |source: &Path, field: &Path, like: &Path, output: &Path| {
        posereg(&[
            "resample",
            s(source),
            "--field",
            s(field),
            "--like",
            s(like),
            "-o",
            s(output),
            "--device",
            "cpu",
        ])
    };
    assert_fails_naming(
        &run(&dir.path().join("absent.nii.gz"), &field, &src, &out),
        "absent.nii.gz",
    );
    assert_fails_naming(&run(&truncated, &field, &src, &out), "truncated.nii.gz");
    assert_fails_naming(&run(&src, &field, &other_grid, &out), "field.nii.gz");
    assert_fails_naming(&run(&src, &src, &src, &out), "source.nii.gz");
    assert_fails_naming(
        &run(&src, &field, &src, &dir.path().join("nowhere/out.nii.gz")),
        "out.nii.gz",
    );
    assert!(!out.exists());
    let stray: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains("posereg-tmp"))
        .collect();
    assert!(stray.is_empty(), "temporary files left: {stray:?}");
}

#[test]
fn info_on_a_missing_or_corrupt_file_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let corrupt = dir.path().join("corrupt.nii");
    std::fs::write(&corrupt, vec![7u8; 400]).unwrap();
    assert_fails_naming(&posereg(&["info", s(&corrupt)]), "corrupt.nii");
    assert_fails_naming(&posereg(&["info", "/no/such/file.nii.gz"]), "file.nii.gz");
}

/// Runs `verb` (init or register) on the demo folder's source, labels and target into `out`,
/// on the CPU, with `extra` flags, checks it succeeded and returns its stderr.
fn run_on_pair(verb: &str, demo: &Path, out: &Path, extra: &[&str]) -> String {
    let [source, labels, target] =
        ["source.nii.gz", "source_labels.nii.gz", "target.nii.gz"].map(|f| demo.join(f));
    let mut args = vec![
        verb,
        "--source",
        s(&source),
        "--source-labels",
        s(&labels),
        "--target",
        s(&target),
        "-o",
        s(out),
        "--device",
        "cpu",
    ];
    args.extend(extra);
    let result = posereg(&args);
    let stderr = String::from_utf8_lossy(&result.stderr).into_owned();
    assert!(result.status.success(), "{verb}: {stderr}");
    stderr
}

#[test]
fn demo_bend_and_init_run_end_to_end_on_a_small_phantom() {
    let dir = tempfile::tempdir().unwrap();
    let demo = dir.path().join("demo");
    let out = posereg(&[
        "demo",
        "--size",
        "small",
        "--flexion",
        "30",
        "-o",
        s(&demo),
        "--device",
        "cpu",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("mean error") && stdout.contains("correlation"),
        "{stdout}"
    );
    // Off a terminal, progress is one stderr line per step.
    let stderr = String::from_utf8_lossy(&out.stderr);
    for stage in [
        "initialisation [1/",
        "adaptive RBF [1/",
        "adaptive RBF: done in",
        "dense refinement, level 1 [1/",
    ] {
        assert!(stderr.contains(stage), "no '{stage}' in stderr: {stderr}");
    }
    // demo writes what register writes, and its inputs.
    for file in [
        "warped.nii.gz",
        "field.nii.gz",
        "inverse_field.nii.gz",
        "jacobian.nii.gz",
        "transform.json",
        "bones/tibia.tfm",
        "report.json",
        "quicklook.png",
        "posereg.log",
        "kinematics.json",
        "target.nii.gz",
        "source_labels.nii.gz",
    ] {
        assert!(demo.join(file).exists(), "demo did not write {file}");
    }
    // The knee bent 30°: the tibiofemoral flexion changes by about that much.
    let csv = std::fs::read_to_string(demo.join("kinematics.csv")).unwrap();
    let flexion: f64 = csv
        .lines()
        .find(|l| l.starts_with("tibiofemoral,flexion,deg,"))
        .and_then(|l| l.rsplit(',').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no tibiofemoral flexion in {csv}"));
    assert!(
        (flexion - 30.0).abs() < 2.0,
        "flexion changed by {flexion}°"
    );
    // init on the demo's pair writes its three outputs.
    let init = dir.path().join("init");
    let stderr = run_on_pair("init", &demo, &init, &["--quiet"]);
    assert!(stderr.is_empty(), "--quiet printed: {stderr}");
    for file in ["init.json", "init_field.nii.gz", "initialised.nii.gz"] {
        assert!(init.join(file).exists(), "init did not write {file}");
    }
    let transforms = posereg::io::transform::BoneTransforms::load(&init.join("init.json")).unwrap();
    assert_eq!(transforms.space, "RAS");
    assert_eq!(transforms.bones.len(), 4);
    // bend on the straight phantom: a 20° bend with its truth.
    let bent = dir.path().join("bent");
    let out = posereg(&[
        "bend",
        s(&demo.join("source.nii.gz")),
        "--labels",
        s(&demo.join("source_labels.nii.gz")),
        "--degrees",
        "20",
        "-o",
        s(&bent),
        "--device",
        "cpu",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let truth = posereg::io::transform::BoneTransforms::load(&bent.join("truth.json")).unwrap();
    let tibia = truth.bones.iter().find(|b| b.label == 3).unwrap().affine();
    let angle = ((tibia[(0, 0)] + tibia[(1, 1)] + tibia[(2, 2)] - 1.0) / 2.0)
        .acos()
        .to_degrees();
    assert!((angle - 20.0).abs() < 1e-6, "tibia turned {angle}°");
    assert!(bent.join("target.nii.gz").exists() && bent.join("truth_field.nii.gz").exists());
    // register runs the whole pipeline on the demo's 30° pair: its outputs and report.
    // Settings: a config file's value, and a flag over the file's.
    let reg = dir.path().join("reg");
    let settings = dir.path().join("settings.toml");
    std::fs::write(
        &settings,
        "[adaptive]\niterations = \"20x20x10\"\nthreshold = 6.0\n",
    )
    .unwrap();
    let flags = ["--config", s(&settings), "--threshold", "9x8x8"];
    run_on_pair("register", &demo, &reg, &flags);
    for file in [
        "warped.nii.gz",
        "field.nii.gz",
        "inverse_field.nii.gz",
        "transform.json",
        "jacobian.nii.gz",
        "report.json",
        "posereg.log",
    ] {
        assert!(reg.join(file).exists(), "register did not write {file}");
    }
    let log = std::fs::read_to_string(reg.join("posereg.log")).unwrap();
    assert!(
        log.contains("9x8x8") && log.contains("registered in"),
        "{log}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(reg.join("report.json")).unwrap()).unwrap();
    let (before, after) = (
        report["correlation"]["before"].as_f64().unwrap(),
        report["correlation"]["after"].as_f64().unwrap(),
    );
    assert!(after > before, "correlation {before} -> {after}");
    assert_eq!(report["schema"], 1);
    let command = report["command_line"].as_array().unwrap();
    assert!(command.iter().any(|a| a == "9x8x8"), "{command:?}");
    assert!(report["finished_unix_seconds"].as_u64().unwrap() > 1_700_000_000);
    assert!(
        reg.join("bones/femur.tfm").exists(),
        "register wrote no bones/femur.tfm"
    );
    let used = &report["options"]["adaptive"];
    assert_eq!(used["iterations"], "20x20x10", "from the config file");
    assert_eq!(used["threshold"], "9x8x8", "the flag overrides the file");
    let warped = load_volume(&reg.join("warped.nii.gz")).unwrap();
    let target = load_volume(&demo.join("target.nii.gz")).unwrap();
    assert_eq!(warped.grid, target.grid, "warped is on the target's grid");
    // The inverse field brings the target back onto the source's grid.
    let trip = &report["inverse_round_trip"];
    assert!(trip["mean_mm"].as_f64().unwrap() < 0.01, "{trip}");
    let back = dir.path().join("back.nii.gz");
    let source_path = demo.join("source.nii.gz");
    let applied = posereg(&[
        "apply",
        s(&reg.join("transform.json")),
        s(&demo.join("target.nii.gz")),
        "--like",
        s(&source_path),
        "--inverse",
        "-o",
        s(&back),
        "--device",
        "cpu",
    ]);
    assert!(applied.status.success(), "{applied:?}");
    let (back, source) = (
        load_volume(&back).unwrap(),
        load_volume(&source_path).unwrap(),
    );
    assert_eq!(back.grid, source.grid);
    let body = |n: usize| source.data[n] > 0.0;
    let r = posereg::images::metric::correlation(&back.data, &source.data, body);
    assert!(
        r > 0.9,
        "target brought back correlates {r} with the source"
    );
}

/// Every bad input of issue 6 — missing file, NaN voxels, labels on another grid, labels
/// without bones, scans that do not overlap, a misspelt setting — fails in one line naming the
/// file, with a non-zero exit and no output folder.
#[test]
fn register_refuses_each_bad_input_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name);
    let grid = oblique_grid([10, 9, 8]);
    save_volume(
        &path("source.nii.gz"),
        &smooth_volume(&grid, 1),
        DataType::F32,
    )
    .unwrap();
    let bones = posereg::Image::filled(grid.clone(), 2u16);
    posereg::io::nifti::save_labels(&path("labels.nii.gz"), &bones).unwrap();
    let mut nan = smooth_volume(&grid, 2);
    nan.data[17] = f32::NAN;
    save_volume(&path("nan_target.nii.gz"), &nan, DataType::F32).unwrap();
    let other_grid = posereg::Image::filled(oblique_grid([10, 9, 9]), 2u16);
    posereg::io::nifti::save_labels(&path("wrong_labels.nii.gz"), &other_grid).unwrap();
    let no_bones = posereg::Image::filled(grid.clone(), 1u16);
    posereg::io::nifti::save_labels(&path("empty_labels.nii.gz"), &no_bones).unwrap();
    let mut far = smooth_volume(&grid, 3);
    far.grid.affine[(0, 3)] += 1000.0;
    save_volume(&path("far_target.nii.gz"), &far, DataType::F32).unwrap();
    std::fs::write(path("typo.toml"), "[adaptive]\niteratoins = 5\n").unwrap();
    let out = path("out");
    let cases = [
        ("missing.nii.gz", "labels.nii.gz", "source.nii.gz", None),
        ("source.nii.gz", "labels.nii.gz", "nan_target.nii.gz", None),
        (
            "source.nii.gz",
            "wrong_labels.nii.gz",
            "source.nii.gz",
            None,
        ),
        (
            "source.nii.gz",
            "empty_labels.nii.gz",
            "source.nii.gz",
            None,
        ),
        ("source.nii.gz", "labels.nii.gz", "far_target.nii.gz", None),
        (
            "source.nii.gz",
            "labels.nii.gz",
            "source.nii.gz",
            Some("typo.toml"),
        ),
    ];
    for (source, labels, target, config) in cases {
        let (src, lab, tgt) = (path(source), path(labels), path(target));
        let mut args = vec![
            "register",
            "--source",
            s(&src),
            "--source-labels",
            s(&lab),
            "--target",
            s(&tgt),
            "-o",
            s(&out),
            "--device",
            "cpu",
        ];
        let settings = config.map(path);
        if let Some(settings) = &settings {
            args.extend(["--config", s(settings)]);
        }
        let culprit = config.unwrap_or(match (source, labels, target) {
            (s, _, _) if s != "source.nii.gz" => s,
            (_, l, _) if l != "labels.nii.gz" => l,
            (_, _, t) => t,
        });
        assert_fails_naming(&posereg(&args), culprit);
        assert!(
            !out.exists(),
            "no output folder after a failure on {culprit}"
        );
    }
}

/// `--dense` and `--no-dense` mean the same for `demo` (and `series`, which shares the flags)
/// as for `register`: report.json says which stage ran on how many levels. `--dense` over a
/// settings file that turns the stage off runs it on the file's levels (one, whose settings
/// the file leaves at the defaults' finest values, as report.json's options record).
#[test]
fn demo_takes_the_dense_flags() {
    let dir = tempfile::tempdir().unwrap();
    let off = dir.path().join("off.toml");
    let settings = "[dense]\nenabled = false\nlevels = 1\niterations = 3\n";
    std::fs::write(&off, settings).unwrap();
    let off = s(&off);
    let cases: [(&[&str], _); 2] = [
        (&["--no-dense"], None),
        (&["--config", off, "--dense"], Some(1)),
    ];
    for (flags, levels) in cases {
        let flag = flags[flags.len() - 1];
        let demo = dir.path().join(flag);
        let to = ["-o", s(&demo), "--device", "cpu"];
        let args = [&["demo", "--size", "quarter"][..], flags, &to].concat();
        let out = posereg(&args);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let report = std::fs::read_to_string(demo.join("report.json")).unwrap();
        let report: serde_json::Value = serde_json::from_str(&report).unwrap();
        let ran = report["dense"]["levels"].as_array().map(|l| l.len());
        assert_eq!(ran, levels, "{flag}: {}", report["dense"]);
        if levels == Some(1) {
            // The report records what the one level read of the three-level defaults.
            let used = &report["options"]["dense"];
            let read = (&used["fluid_sigma"], &used["momentum"], &used["iterations"]);
            assert_eq!(read, (&2.0.into(), &0.25.into(), &3.into()), "{used}");
        }
    }
}

/// A settings file whose per-level dense values do not fit its `levels` is refused before any
/// input is read: one error naming the file and each such setting, and no output folder.
#[test]
fn a_file_whose_dense_values_do_not_fit_its_levels_is_refused_naming_each_setting() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name);
    let two_levels = path("two_levels.toml");
    let settings = "[dense]\nlevels = 2\niterations = \"50x40x20\"\nmomentum = \"0.5x0.4x0.2\"\n";
    std::fs::write(&two_levels, settings).unwrap();
    let (scan, out) = (path("missing.nii.gz"), path("out"));
    let args = [
        "register",
        "--source",
        s(&scan),
        "--source-labels",
        s(&scan),
        "--target",
        s(&scan),
        "--config",
        s(&two_levels),
        "-o",
        s(&out),
    ];
    let refused = posereg(&args);
    assert_fails_naming(&refused, "two_levels.toml");
    for name in ["dense.iterations", "dense.momentum"] {
        assert_fails_naming(&refused, name);
    }
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !stderr.contains("fluid_sigma"),
        "a setting left at its default is not named: {stderr}"
    );
    assert!(
        !out.exists(),
        "no output folder after a refused settings file"
    );
}

#[test]
fn apply_apply_points_and_eval_use_a_registration_folder() {
    // A "registration" whose field is a phantom's exact truth, so every answer is known.
    let dir = tempfile::tempdir().unwrap();
    let spec = |flexion_degrees, seed| posereg::phantom::PhantomSpec {
        size: posereg::phantom::PhantomSize::Small,
        flexion_degrees,
        seed,
        ..Default::default()
    };
    let straight = posereg::phantom::generate(&spec(0.0, 1)).unwrap();
    let bent = posereg::phantom::generate(&spec(30.0, 2)).unwrap();
    let reg = dir.path().join("reg");
    std::fs::create_dir_all(&reg).unwrap();
    save_field(&reg.join("field.nii.gz"), &bent.truth_field).unwrap();
    bent.truth.save(&reg.join("transform.json")).unwrap();
    let target = dir.path().join("target.nii.gz");
    save_volume(&target, &bent.image, DataType::F32).unwrap();
    let labels = dir.path().join("labels.nii.gz");
    posereg::io::nifti::save_labels(&labels, &straight.labels).unwrap();

    // apply --nearest carries the straight labels onto the bent ones.
    let moved = dir.path().join("moved_labels.nii.gz");
    let out = posereg(&[
        "apply",
        s(&reg.join("transform.json")),
        s(&labels),
        "--like",
        s(&target),
        "-o",
        s(&moved),
        "--nearest",
        "--device",
        "cpu",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let moved = posereg::io::nifti::load_labels(&moved).unwrap();
    let d = posereg::images::metric::dice(&moved.data, &bent.labels.data, 3u16);
    assert!(d > 0.9, "tibia Dice {d}");

    // apply-points: the patella's centre on the straight scan lands on the bent patella's
    // centre (the truth's rigid motion of it), and comes back.
    let grid = &straight.labels.grid;
    let (mut sum, mut n) = (nalgebra::Vector3::zeros(), 0.0);
    for (k, &l) in straight.labels.data.iter().enumerate() {
        if l == 4 {
            sum += grid.world_of(k);
            n += 1.0;
        }
    }
    let centre = sum / n;
    let csv = dir.path().join("points.csv");
    std::fs::write(
        &csv,
        format!(
            "name,x,y,z\npatella,{},{},{}\n",
            centre.x, centre.y, centre.z
        ),
    )
    .unwrap();
    let there = dir.path().join("there.csv");
    let out = posereg(&[
        "apply-points",
        s(&reg.join("transform.json")),
        s(&csv),
        "-o",
        s(&there),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let row = |path: &Path| -> nalgebra::Vector3<f64> {
        let text = std::fs::read_to_string(path).unwrap();
        let cells: Vec<f64> = text
            .lines()
            .nth(1)
            .unwrap()
            .split(',')
            .skip(1)
            .take(3)
            .map(|c| c.parse().unwrap())
            .collect();
        nalgebra::Vector3::new(cells[0], cells[1], cells[2])
    };
    let m = bent
        .truth
        .bones
        .iter()
        .find(|b| b.label == 4)
        .unwrap()
        .affine();
    let expected = (m * centre.push(1.0)).xyz();
    let got = row(&there);
    assert!(
        (got - expected).norm() < 0.5,
        "patella centre mapped to {got:?}, truth {expected:?}"
    );
    assert!(std::fs::read_to_string(&there)
        .unwrap()
        .starts_with("name,x,y,z,inversion_residual_mm\npatella,"));
    let back = dir.path().join("back.csv");
    let out = posereg(&[
        "apply-points",
        s(&reg.join("transform.json")),
        s(&there),
        "-o",
        s(&back),
        "--direction",
        "target-to-source",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!((row(&back) - centre).norm() < 0.5);

    // eval of the truth against itself.
    let out = posereg(&[
        "eval",
        "--field",
        s(&reg.join("field.nii.gz")),
        "--truth",
        s(&reg.join("field.nii.gz")),
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["mean_mm"].as_f64(), Some(0.0));
    assert_eq!(v["within_2_voxels"].as_f64(), Some(1.0));
    // A points file without a z column is refused, naming the file.
    let bad = dir.path().join("bad_points.csv");
    std::fs::write(&bad, "x,y\n1,2\n").unwrap();
    assert_fails_naming(
        &posereg(&[
            "apply-points",
            s(&reg.join("transform.json")),
            s(&bad),
            "-o",
            s(&there),
        ]),
        "bad_points.csv",
    );
}

/// A quarter-size phantom pair (0° and 30°) in `dir`: source image, its labels, target.
fn quarter_pair(dir: &Path) -> [PathBuf; 3] {
    for (flexion, seed, name) in [("0", "1", "straight"), ("30", "2", "bent")] {
        let out = dir.join(name);
        let args = ["phantom", "--size", "quarter", "--flexion", flexion];
        let made = posereg(&[&args[..], &["--seed", seed, "-q", "-o", s(&out)]].concat());
        assert!(made.status.success(), "{made:?}");
    }
    [
        dir.join("straight/image.nii.gz"),
        dir.join("straight/labels.nii.gz"),
        dir.join("bent/image.nii.gz"),
    ]
}

/// Runs `verb` on the three inputs into `out` on the CPU, with `extra` flags.
fn run_verb(
    verb: &str,
    [source, labels, target]: &[PathBuf; 3],
    out: &Path,
    extra: &[&str],
) -> Output {
    let inputs = [
        "--source",
        s(source),
        "--source-labels",
        s(labels),
        "--target",
        s(target),
    ];
    let base = [
        &[verb][..],
        &inputs,
        &["-o", s(out), "--device", "cpu", "-q"],
    ]
    .concat();
    posereg(&[&base[..], extra].concat())
}

fn bone_motions(path: &Path) -> Vec<(String, [[f64; 4]; 4])> {
    let t = posereg::io::transform::BoneTransforms::load(path).unwrap();
    t.bones.into_iter().map(|b| (b.name, b.matrix)).collect()
}

/// The cartilage layout (1 femur, 2 femoral cartilage, 3 tibia, …) read through --label-map
/// registers the same bones as posereg's own codes, bit for bit; the --moving/--fixed aliases
/// name the same inputs; bad maps are refused before any output is written.
#[test]
fn a_label_map_in_another_layout_registers_the_same_bones() {
    let dir = tempfile::tempdir().unwrap();
    let pair = quarter_pair(dir.path());
    let own = dir.path().join("own");
    let ran = run_verb("init", &pair, &own, &[]);
    assert!(ran.status.success(), "{ran:?}");
    // posereg's codes 1 soft tissue, 2 femur, 3 tibia, 4 patella, 5 fibula → 2 (as if
    // cartilage), 1, 3, 6, 8.
    let mut labels = posereg::io::nifti::load_labels(&pair[1]).unwrap();
    let layout = [0u16, 2, 1, 3, 6, 8];
    labels
        .data
        .iter_mut()
        .for_each(|c| *c = layout[*c as usize]);
    let relabelled = dir.path().join("cartilage_layout.nii.gz");
    posereg::io::nifti::save_labels(&relabelled, &labels).unwrap();
    let map = "femur=1,tibia=3,patella=6,fibula=8";
    let theirs = dir.path().join("theirs");
    let aliased = [
        "init",
        "--moving",
        s(&pair[0]),
        "--moving-labels",
        s(&relabelled),
        "--fixed",
        s(&pair[2]),
        "-o",
        s(&theirs),
        "--device",
        "cpu",
        "--label-map",
        map,
    ];
    let ran = posereg(&aliased);
    let said = String::from_utf8_lossy(&ran.stderr);
    assert!(ran.status.success(), "{said}");
    assert!(said.contains("label codes 2 are not bones"), "{said}");
    assert_eq!(
        bone_motions(&own.join("init.json")),
        bone_motions(&theirs.join("init.json"))
    );
    let codes: Vec<u16> = posereg::io::transform::BoneTransforms::load(&theirs.join("init.json"))
        .unwrap()
        .bones
        .iter()
        .map(|b| b.label)
        .collect();
    assert_eq!(codes, [1, 3, 6, 8]);
    let no = dir.path().join("refused");
    let relabelled_pair = [pair[0].clone(), relabelled.clone(), pair[2].clone()];
    for (map, problem) in [
        ("femur=1,tibai=3", "no bone named \"tibai\""),
        ("femur=1,tibia=1", "repeats"),
        ("tibia=3,fibula=8", "root, femur, is not"),
        ("femur", "not name=code"),
        ("femur=-1", "not a label code"),
    ] {
        let out = run_verb("register", &relabelled_pair, &no, &["--label-map", map]);
        let said = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && said.contains(problem),
            "{map}: {said}"
        );
        assert!(said.contains("--label-map"), "{said}");
        assert!(!no.exists(), "{map} left an output folder");
    }
}

/// `register --init` starts from given bone motions and keeps them; it cannot be combined
/// with --no-init.
#[test]
fn register_init_starts_from_the_given_bones() {
    let dir = tempfile::tempdir().unwrap();
    let pair = quarter_pair(dir.path());
    let init = dir.path().join("init");
    assert!(run_verb("init", &pair, &init, &[]).status.success());
    let given = init.join("init.json");
    assert!(
        init.join("kinematics.csv").exists(),
        "init wrote no kinematics"
    );
    // --side against the labels' fibula: kept, with a warning.
    let left = run_verb("init", &pair, &dir.path().join("left"), &["--side", "left"]);
    let said = String::from_utf8_lossy(&left.stderr);
    assert!(
        left.status.success() && said.contains("contradicts"),
        "{said}"
    );
    let reg = dir.path().join("reg");
    let fast = ["--iterations", "3x3x3", "--init", s(&given)];
    let ran = run_verb("register", &pair, &reg, &fast);
    assert!(ran.status.success(), "{ran:?}");
    assert_eq!(
        bone_motions(&given),
        bone_motions(&reg.join("transform.json"))
    );
    let both = run_verb(
        "register",
        &pair,
        &dir.path().join("no"),
        &["--no-init", "--init", s(&given)],
    );
    assert!(!both.status.success());
    assert!(String::from_utf8_lossy(&both.stderr).contains("--no-init"));
}

/// `posereg devices` lists the adapters --gpu counts; an index past the list is refused naming
/// the list, and --gpu 0 runs on the first.
#[test]
fn gpu_by_index_and_the_device_list() {
    let Some(_) = gpu() else { return };
    let listed = posereg(&["devices"]);
    let text = String::from_utf8_lossy(&listed.stdout);
    assert!(listed.status.success() && text.starts_with("0: "), "{text}");
    let dir = tempfile::tempdir().unwrap();
    let (_, src, field) = source_and_zero_field(dir.path(), [9, 8, 7], 3);
    let out_path = dir.path().join("out.nii.gz");
    let first = resample_onto_itself(&src, &field, &out_path, &["--gpu", "0"]);
    assert!(first.status.success(), "{first:?}");
    let count = text.lines().count().to_string();
    let past = resample_onto_itself(
        &src,
        &field,
        &dir.path().join("x.nii.gz"),
        &["--gpu", &count],
    );
    assert_fails_naming(&past, &format!("--gpu {count}"));
    let named = resample_onto_itself(&src, &field, &out_path, &["--gpu", "no-such-gpu"]);
    assert_fails_naming(&named, "matches none");
}

/// --target-mask: a mask of the whole target changes nothing, bit for bit; a slab of it leaves
/// the rest out of the non-rigid fit (fewer control points); a mask on another grid or nearly
/// empty is refused naming the file, leaving no output folder.
#[test]
fn a_target_mask_limits_the_evidence() {
    let dir = tempfile::tempdir().unwrap();
    let pair = quarter_pair(dir.path());
    let target = load_volume(&pair[2]).unwrap();
    let save_mask = |name: &str, keep: &dyn Fn(usize) -> bool| {
        let [nx, ny, _] = target.grid.dims;
        let data = (0..target.grid.len())
            .map(|n| keep(n / (nx * ny)) as u16)
            .collect();
        let mask = posereg::Image::from_data(target.grid.clone(), data).unwrap();
        let path = dir.path().join(name);
        posereg::io::nifti::save_labels(&path, &mask).unwrap();
        path
    };
    let whole = save_mask("whole.nii.gz", &|_| true);
    let slab = save_mask("slab.nii.gz", &|k| k < target.grid.dims[2] / 3);
    let empty = save_mask("empty.nii.gz", &|_| false);
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let ran = run_verb("register", &pair, &out, extra);
        assert!(ran.status.success(), "{ran:?}");
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                .unwrap();
        let field = posereg::io::field::load_field(&out.join("field.nii.gz")).unwrap();
        (report["control_points"].as_u64().unwrap(), field.data)
    };
    let (points, field) = run("plain", &[]);
    let (_, whole_field) = run("whole", &["--target-mask", s(&whole)]);
    assert!(
        field == whole_field,
        "a mask of the whole target changed the field"
    );
    let (slab_points, _) = run("slab", &["--fixed-mask", s(&slab)]);
    assert!(
        slab_points < points,
        "slab mask: {slab_points} control points, {points} without"
    );
    let other_grid = dir.path().join("other.nii.gz");
    let straight_labels = posereg::io::nifti::load_labels(&pair[1]).unwrap();
    let mut moved = straight_labels.clone();
    moved.grid.affine[(0, 3)] += 7.0;
    posereg::io::nifti::save_labels(&other_grid, &moved).unwrap();
    let no = dir.path().join("refused");
    for (mask, problem) in [(&other_grid, "target's grid"), (&empty, "too few")] {
        let out = run_verb("register", &pair, &no, &["--target-mask", s(mask)]);
        assert_fails_naming(&out, s(mask));
        assert!(String::from_utf8_lossy(&out.stderr).contains(problem));
        assert!(!no.exists());
    }
}

/// `posereg pose` writes the source re-posed with its truth; a flexion beyond ±150° is
/// refused before anything is written.
#[test]
fn pose_writes_a_posed_pair_with_its_truth() {
    let dir = tempfile::tempdir().unwrap();
    let [source, labels, _] = quarter_pair(dir.path());
    let out = dir.path().join("posed");
    let args = [
        "pose",
        s(&source),
        "--labels",
        s(&labels),
        "--device",
        "cpu",
        "-o",
        s(&out),
    ];
    let ran = posereg(&[&args[..], &["--flexion", "25", "--varus", "-2", "-q"]].concat());
    assert!(ran.status.success(), "{ran:?}");
    for file in [
        "target.nii.gz",
        "target_labels.nii.gz",
        "truth_field.nii.gz",
        "picture.png",
    ] {
        assert!(out.join(file).exists(), "pose did not write {file}");
    }
    let truth = posereg::io::transform::BoneTransforms::load(&out.join("truth.json")).unwrap();
    assert_eq!(truth.bones.len(), 4);
    assert_eq!(
        truth.extra["pose"]["tibiofemoral_change"]["varus_deg"],
        -2.0
    );
    let far = dir.path().join("far");
    let refused = posereg(&[
        "pose",
        s(&source),
        "--labels",
        s(&labels),
        "--flexion",
        "200",
        "-o",
        s(&far),
    ]);
    assert_fails_naming(&refused, "flexion");
    assert!(!far.exists());
}

/// `posereg series` of `inputs` (quarter_series') into `out` on the CPU with the settings
/// file `config` and `extra` flags; fails the test unless it succeeds, returns what it printed.
fn run_series(inputs: &[PathBuf; 4], out: &Path, config: &Path, extra: &[&str]) -> String {
    let [source, labels, thirty, sixty] = inputs;
    let args = [
        "series",
        "--source",
        s(source),
        "--source-labels",
        s(labels),
        "--targets",
    ];
    let rest = [
        s(thirty),
        s(sixty),
        "-o",
        s(out),
        "--device",
        "cpu",
        "--config",
        s(config),
    ];
    let ran = posereg(&[&args[..], &rest, extra].concat());
    assert!(ran.status.success(), "{ran:?}");
    String::from_utf8_lossy(&[ran.stdout, ran.stderr].concat()).to_string()
}

/// quarter_pair's source, labels and 30° target, and a 60° target: a series of two poses.
fn quarter_series(dir: &Path) -> [PathBuf; 4] {
    let [source, labels, thirty] = quarter_pair(dir);
    let sixty = dir.join("sixty");
    let args = [
        "phantom",
        "--size",
        "quarter",
        "--flexion",
        "60",
        "--seed",
        "3",
        "-q",
        "-o",
    ];
    let made = posereg(&[&args[..], &[s(&sixty)]].concat());
    assert!(made.status.success(), "{made:?}");
    [source, labels, thirty, sixty.join("image.nii.gz")]
}

/// `posereg series` registers each pose into its own folder, the second reached through the
/// first, and tabulates and plots the kinematics of every pose (series.csv, series.json,
/// series.png).
#[test]
fn series_registers_every_pose_and_tabulates_them() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = quarter_series(dir.path());
    let (out, fast) = (dir.path().join("series"), fast_settings(dir.path()));
    run_series(&inputs, &out, &fast, &["-q"]);
    for pose in ["pose_01", "pose_02"] {
        assert!(out.join(pose).join("kinematics.csv").exists(), "no {pose}");
    }
    let start = |out: &Path, pose: &str| {
        let report = std::fs::read_to_string(out.join(pose).join("report.json")).unwrap();
        let report: serde_json::Value = serde_json::from_str(&report).unwrap();
        report["inputs"]["start"].as_str().unwrap().to_string()
    };
    assert!(start(&out, "pose_01").starts_with("identity"));
    assert!(start(&out, "pose_02").starts_with("chained"));
    let summary = std::fs::read_to_string(out.join("series.json")).unwrap();
    let summary: serde_json::Value = serde_json::from_str(&summary).unwrap();
    let poses = summary["poses"].as_array().unwrap();
    assert_eq!(poses.len(), 2);
    assert!(
        poses[1]["registration"]["correlation"]["after"]
            .as_f64()
            .unwrap()
            > 0.8
    );
    assert_eq!(poses[1]["kinematics"][0]["joint"], "tibiofemoral");
    let png = std::fs::read(out.join("series.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG"), "series.png is not a PNG");
    let table = std::fs::read_to_string(out.join("series.csv")).unwrap();
    let flexion: Vec<f64> = table
        .lines()
        .filter(|l| l.contains(",tibiofemoral,flexion,"))
        .map(|l| l.rsplit(',').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(flexion.len(), 2, "{table}");
    assert!(
        (flexion[0] - 30.0).abs() < 3.0 && (flexion[1] - 60.0).abs() < 3.0,
        "{flexion:?}"
    );
    // --unchained: the second pose registered from the source, the first pose's bones tried
    // first.
    let unchained = dir.path().join("unchained");
    run_series(&inputs, &unchained, &fast, &["--unchained", "-q"]);
    assert!(start(&unchained, "pose_02").starts_with("seeded"));
}

/// `posereg series` run again on its folder resumes after the last pose finished from the same
/// inputs and settings: the poses after it come out with the bytes of one whole run, the
/// finished ones are not written again; changed settings register every pose again.
#[test]
fn a_series_run_again_resumes_after_its_last_finished_pose_with_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = quarter_series(dir.path());
    let fast = fast_settings(dir.path());
    let series = |out: &Path, config: &Path| run_series(&inputs, out, config, &[]);
    let whole = dir.path().join("whole");
    series(&whole, &fast);
    // A run stopped after its first pose: series.json holds that pose only, pose_02 is gone.
    let resumed = dir.path().join("resumed");
    copy_folder(&whole, &resumed);
    let path = resumed.join("series.json");
    let mut record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    record["poses"].as_array_mut().unwrap().truncate(1);
    std::fs::write(&path, serde_json::to_string_pretty(&record).unwrap()).unwrap();
    std::fs::remove_dir_all(resumed.join("pose_02")).unwrap();
    std::fs::remove_file(resumed.join("series.csv")).unwrap();
    let first = resumed.join("pose_01/field.nii.gz");
    let written_at = || std::fs::metadata(&first).unwrap().modified().unwrap();
    let before = written_at();
    let log = series(&resumed, &fast);
    assert!(log.contains("resuming after pose 1"), "{log}");
    assert!(!log.contains("pose 1 of 2"), "{log}");
    assert_eq!(written_at(), before, "pose 1 was written again");
    for file in [
        "field.nii.gz",
        "inverse_field.nii.gz",
        "warped.nii.gz",
        "transform.json",
    ] {
        let read = |out: &Path| std::fs::read(out.join("pose_02").join(file)).unwrap();
        assert!(read(&whole) == read(&resumed), "pose_02/{file} differs");
    }
    let table = |out: &Path| std::fs::read_to_string(out.join("series.csv")).unwrap();
    assert_eq!(table(&whole), table(&resumed));
    // Finished: nothing registered again.
    let log = series(&resumed, &fast);
    assert!(
        log.contains("resuming after pose 2") && !log.contains("of 2:"),
        "{log}"
    );
    let kept = "2 poses registered (2 kept from an earlier run)";
    assert!(log.contains(kept), "{log}");
    // One target fewer: the first pose is kept, the second's folder is said to be stale.
    let ran = posereg(&[
        "series",
        "--source",
        s(&inputs[0]),
        "--source-labels",
        s(&inputs[1]),
        "--targets",
        s(&inputs[2]),
        "-o",
        s(&resumed),
        "--device",
        "cpu",
        "--config",
        s(&fast),
    ]);
    let log = String::from_utf8_lossy(&ran.stderr);
    assert!(
        ran.status.success() && log.contains("pose_02 and any later pose folder"),
        "{log}"
    );
    // Other settings: every pose again.
    let other = dir.path().join("other.toml");
    std::fs::write(&other, "[adaptive]\niterations = \"2x2x2\"\n").unwrap();
    let log = series(&resumed, &other);
    assert!(
        log.contains("pose 1 of 2") && !log.contains("resuming"),
        "{log}"
    );
    assert_ne!(written_at(), before, "pose 1 was not registered again");
}

/// Copies the files of `from` and its folders into `to`.
fn copy_folder(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let (path, copy) = (entry.path(), to.join(entry.file_name()));
        match path.is_dir() {
            true => copy_folder(&path, &copy),
            false => drop(std::fs::copy(&path, &copy).unwrap()),
        }
    }
}

/// A settings file that keeps the adaptive stage short (these tests are about the verbs).
fn fast_settings(dir: &Path) -> PathBuf {
    let path = dir.join("fast.toml");
    std::fs::write(&path, "[adaptive]\niterations = \"3x3x3\"\n").unwrap();
    path
}

#[test]
fn a_reader_that_goes_away_ends_the_command_without_a_panic() {
    // `posereg info --json x.nii.gz | head -1`: the reader closes the pipe before the output.
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_posereg"))
        .args(["info", "--json", s(&data.join("oblique_nibabel.nii.gz"))])
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("the binary runs");
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("the binary ends");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.is_empty(), "{stderr}");
}

#[test]
fn a_folder_another_run_writes_into_is_refused_and_a_killed_runs_lock_is_taken_over() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let lock = out.join(posereg::io::lock::LOCK_NAME);
    let host = posereg::io::lock::host();
    let phantom = || posereg(&["phantom", "--size", "quarter", "-o", s(&out)]);
    // A run that is alive (this test's own process) holds the folder.
    std::fs::write(&lock, format!("{} {host}\n", std::process::id())).unwrap();
    let refused = phantom();
    assert_fails_naming(&refused, "in use by another posereg run");
    assert!(!out.join("image.nii.gz").exists());
    assert!(lock.exists(), "the other run's lock is left alone");
    // A run that was killed: its process is gone, its lock is taken over and removed after.
    let mut gone = std::process::Command::new("true").spawn().unwrap();
    let pid = gone.id();
    gone.wait().unwrap();
    std::fs::write(&lock, format!("{pid} {host}\n")).unwrap();
    let done = phantom();
    assert!(
        done.status.success(),
        "{}",
        String::from_utf8_lossy(&done.stderr)
    );
    assert!(out.join("image.nii.gz").exists());
    assert!(!lock.exists(), "the lock goes with the run");
}

/// `posereg series` whose last target is damaged stops before any pose is registered: no
/// pose folder, no table, the damaged file named.
#[test]
fn series_checks_every_target_before_registering_the_first() {
    let dir = tempfile::tempdir().unwrap();
    let [source, labels, thirty] = quarter_pair(dir.path());
    let damaged = dir.path().join("damaged.nii.gz");
    let whole = std::fs::read(&thirty).unwrap();
    std::fs::write(&damaged, &whole[..whole.len() / 2]).unwrap();
    let out = dir.path().join("series");
    let ran = posereg(&[
        "series",
        "--source",
        s(&source),
        "--source-labels",
        s(&labels),
        "--targets",
        s(&thirty),
        s(&damaged),
        "-o",
        s(&out),
        "--device",
        "cpu",
        "-q",
    ]);
    assert_fails_naming(&ran, "damaged.nii.gz");
    assert!(!out.exists(), "the series wrote {out:?} before failing");
}

/// Every file of an output folder, by name relative to it (a folder's files inside it).
fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        match path.is_dir() {
            true => found.extend(files_in(&path)),
            false => found.push(path),
        }
    }
    found.sort();
    found
}

/// `posereg register` killed (SIGKILL) at 20 points spread by a seeded generator over a
/// whole run: every output left under its own name is whole (byte for byte the uninterrupted
/// run's, or for report.json, whose timings differ, JSON that parses); only a write cut short
/// may remain, under its hidden temporary name; the killed run's lock never keeps the folder;
/// and a rerun into the same folder writes the uninterrupted run's bytes.
#[test]
fn runs_killed_anywhere_leave_no_half_written_output_and_a_rerun_gives_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = quarter_pair(dir.path());
    let fast = fast_settings(dir.path());
    let extra = ["--config", s(&fast)];
    let reference = dir.path().join("reference");
    // The kill window is the fastest whole run seen so far: the first run
    // pays for a cold start (page cache, allocator), and a window sized on
    // it would put most kills after a later run has already finished.
    let timed_run = |out: &Path| {
        let started = std::time::Instant::now();
        let whole = run_verb("register", &inputs, out, &extra);
        assert!(whole.status.success(), "{whole:?}");
        started.elapsed().as_secs_f64()
    };
    let mut seconds = timed_run(&reference).min(timed_run(&reference));
    let timed = |name: &str| name == "report.json" || name == "posereg.log";
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut cut_short = 0;
    for k in 0..20 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let at = seconds * (state % 1000) as f64 / 1000.0;
        let out = dir.path().join(format!("killed_{k:02}"));
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_posereg"))
            .args([
                "register",
                "--source",
                s(&inputs[0]),
                "--source-labels",
                s(&inputs[1]),
            ])
            .args([
                "--target",
                s(&inputs[2]),
                "-o",
                s(&out),
                "--device",
                "cpu",
                "-q",
            ])
            .args(extra)
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_secs_f64(at));
        let _ = child.kill();
        child.wait().unwrap();
        cut_short += usize::from(!out.join("posereg.log").exists());
        for path in files_in(&out) {
            let name = path.file_name().unwrap().to_string_lossy().to_string();
            if name.starts_with(".posereg-tmp-") || name == posereg::io::lock::LOCK_NAME {
                continue;
            }
            let relative = path.strip_prefix(&out).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            if name == "report.json" {
                assert!(
                    serde_json::from_slice::<serde_json::Value>(&bytes).is_ok(),
                    "{k}"
                );
            } else if !timed(&name) {
                let want = std::fs::read(reference.join(relative)).unwrap();
                assert!(
                    bytes == want,
                    "kill {k} at {at:.2} s: {relative:?} is not whole"
                );
            }
        }
        seconds = seconds.min(timed_run(&out));
        for path in files_in(&reference) {
            let relative = path.strip_prefix(&reference).unwrap();
            if !timed(&relative.file_name().unwrap().to_string_lossy()) {
                let again = std::fs::read(out.join(relative)).unwrap();
                assert!(again == std::fs::read(&path).unwrap(), "{k}: {relative:?}");
            }
        }
    }
    // Most kill points fall inside the run (the log is its last output), or
    // the test would only have checked finished folders.
    assert!(
        cut_short >= 10,
        "only {cut_short} of 20 kills cut a run short"
    );
}
