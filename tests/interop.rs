//! Runs tests/interop.py (SimpleITK, ANTs and nibabel) on a registration written by
//! `posereg demo` and `posereg apply --inverse`.
//! Without Python or those packages the test is skipped, unless REQUIRE_INTEROP=1 (CI sets it).

use std::process::Command;

fn python_has_packages() -> bool {
    Command::new("python3")
        .args(["-c", "import SimpleITK, nibabel, numpy, ants"])
        .status()
        .map(|s| s.success())
        .unwrap_or(false)
}

#[test]
fn simpleitk_applies_our_field_and_nibabel_reads_our_outputs() {
    if !python_has_packages() {
        assert_ne!(
            std::env::var("REQUIRE_INTEROP").as_deref(),
            Ok("1"),
            "REQUIRE_INTEROP=1 but python3 with SimpleITK, nibabel, numpy and antspyx is missing"
        );
        eprintln!(
            "interop test skipped: python3 with SimpleITK, nibabel, numpy, antspyx not found"
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_posereg"))
        .args([
            "demo",
            "--size",
            "small",
            "--flexion",
            "20",
            "--device",
            "cpu",
            "-o",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let back = dir.path().join("target_on_source.nii.gz");
    let applied = Command::new(env!("CARGO_BIN_EXE_posereg"))
        .arg("apply")
        .arg(dir.path().join("transform.json"))
        .arg(dir.path().join("target.nii.gz"))
        .arg("--like")
        .arg(dir.path().join("source.nii.gz"))
        .args(["--inverse", "--device", "cpu", "-o"])
        .arg(&back)
        .output()
        .unwrap();
    assert!(applied.status.success(), "{applied:?}");
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/interop.py");
    let check = Command::new("python3")
        .arg(script)
        .arg(dir.path())
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&check.stdout);
    eprintln!("{text}{}", String::from_utf8_lossy(&check.stderr));
    assert!(
        check.status.success() && text.contains("interop ok"),
        "interop check failed"
    );
}
