//! Runs tests/workflow.py: the cohort workflow (workflow/Snakefile) on small phantom pairs
//! with Snakemake. Snakemake lives in its own virtual environment (scripts/setup makes
//! .venv from requirements.txt; SNAKEMAKE names another). Without it the
//! test is skipped, unless REQUIRE_INTEROP=1 (CI sets it).

use std::path::PathBuf;
use std::process::Command;

/// The snakemake to run: $SNAKEMAKE, else the repository's .venv, else none.
fn snakemake() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os("SNAKEMAKE") {
        return Some(PathBuf::from(path));
    }
    let venv = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/snakemake");
    venv.exists().then_some(venv)
}

#[test]
fn the_cohort_workflow_runs_resumes_and_lists_failures() {
    let Some(snakemake) = snakemake() else {
        assert_ne!(
            std::env::var("REQUIRE_INTEROP").as_deref(),
            Ok("1"),
            "REQUIRE_INTEROP=1 but snakemake is missing (scripts/setup makes .venv)"
        );
        eprintln!("workflow test skipped: no snakemake (scripts/setup makes .venv)");
        return;
    };
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/workflow.py");
    let out = Command::new("python3")
        .arg(&script)
        .env("POSEREG", env!("CARGO_BIN_EXE_posereg"))
        .env("SNAKEMAKE", &snakemake)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
