//! The settings files the repository ships load as the registration's settings and differ
//! from the defaults only where they say so.

use posereg::io::config::load_options;
use posereg::pipeline::register::RegisterOptions;
use std::path::Path;

#[test]
fn real_scans_toml_loads_and_changes_only_what_it_names() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("real-scans.toml");
    let loaded: RegisterOptions = load_options(&path).expect("real-scans.toml loads");
    let defaults = RegisterOptions::default();
    assert_eq!(loaded.adaptive.threshold.to_string(), "8x8x2");
    assert_eq!(loaded.adaptive.similarity.to_string(), "ssdxssdxlncc");
    // Everything it does not name is the default's.
    let mut expected = defaults.clone();
    expected.adaptive.threshold = loaded.adaptive.threshold.clone();
    expected.adaptive.similarity = loaded.adaptive.similarity.clone();
    assert_eq!(
        serde_json::to_value(&loaded).unwrap(),
        serde_json::to_value(&expected).unwrap(),
        "real-scans.toml changes a setting beyond those it documents"
    );
    assert!(
        loaded.dense.enabled && loaded.dense.levels == 3,
        "real scans get the three-level refinement"
    );
}
