//! The `posereg` binary: verbs, outputs, exit codes and error messages.

mod common;

use common::*;
use posereg::io::field::save_field;
use posereg::io::nifti::{load_volume, save_volume, DataType};
use std::path::Path;
use std::process::{Command, Output};

fn posereg(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_posereg"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("the binary runs")
}

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

#[test]
fn resample_with_a_zero_field_reproduces_the_source_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let grid = oblique_grid([19, 14, 9]);
    let source = smooth_volume(&grid, 31);
    let src = dir.path().join("source.nii.gz");
    let field = dir.path().join("zero.nii.gz");
    save_volume(&src, &source, DataType::F32).unwrap();
    save_field(&field, &constant_field(&grid, [0.0; 3])).unwrap();
    let mut devices = vec!["cpu"];
    if gpu().is_some() {
        devices.push("gpu");
    }
    for device in devices {
        let out_path = dir.path().join(format!("out-{device}.nii.gz"));
        let out = posereg(&[
            "resample",
            s(&src),
            "--field",
            s(&field),
            "--like",
            s(&src),
            "-o",
            s(&out_path),
            "--device",
            device,
        ]);
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
