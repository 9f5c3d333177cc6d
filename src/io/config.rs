//! Settings files: TOML or JSON (chosen by the extension), holding any subset of a settings
//! struct (the registration's is `register::RegisterOptions`); what a file leaves out keeps
//! its default, and an unknown key is an error (a misspelt setting must not be silently
//! ignored).

use crate::error::{Error, Result};
use std::path::Path;

/// Settings a file can hold: every field defaulted, unknown keys refused, and a check of the
/// values that says what is wrong.
pub trait Settings: serde::Serialize + serde::de::DeserializeOwned {
    /// Rejects values the settings' user cannot run with, naming the setting.
    fn check(&self) -> Result<()>;
}

/// Reads a settings file over the defaults.
pub fn load_options<T: Settings>(path: &Path) -> Result<T> {
    parse_options(path, &super::read_text(path)?)
}

/// Settings from the text of the file `path` (whose extension says TOML or JSON), checked.
pub fn parse_options<T: Settings>(path: &Path, text: &str) -> Result<T> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let parsed = match extension.as_deref() {
        Some("toml") => from_toml(text),
        Some("json") => from_json(text),
        _ => Err("a settings file must end in .toml or .json".to_string()),
    };
    let options: T = parsed.map_err(|problem| Error::bad_file(path, problem))?;
    options
        .check()
        .map_err(|problem| Error::bad_file(path, problem.to_string()))?;
    Ok(options)
}

/// Settings from TOML text; a problem names the key it is at (`adaptive.iterations: ...`).
fn from_toml<T: Settings>(text: &str) -> std::result::Result<T, String> {
    let document = toml::Deserializer::parse(text).map_err(|e| e.message().to_string())?;
    serde_path_to_error::deserialize(document).map_err(|e| at_key(e.path(), e.inner().message()))
}

/// Settings from JSON text; a problem names the key it is at.
fn from_json<T: Settings>(text: &str) -> std::result::Result<T, String> {
    let mut document = serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize(&mut document).map_err(|e| at_key(e.path(), e.inner()))
}

/// "key.path: problem", or the problem alone at the top.
fn at_key(path: &serde_path_to_error::Path, problem: impl std::fmt::Display) -> String {
    match path.to_string().as_str() {
        "." => problem.to_string(),
        key => format!("{key}: {problem}"),
    }
}

/// Settings from JSON text handed over rather than read from a file (the Python package's
/// keyword arguments), checked; errors name `what`.
pub fn options_from_json<T: Settings>(what: &str, text: &str) -> Result<T> {
    let problem = |p: String| Error::InvalidInput(format!("{what}: {p}"));
    let options: T = from_json(text).map_err(problem)?;
    options.check().map_err(|e| problem(e.to_string()))?;
    Ok(options)
}

/// The settings as TOML, in the form [`load_options`] reads back.
pub fn options_toml<T: Settings>(options: &T) -> String {
    toml::to_string_pretty(options).unwrap_or_else(|e| format!("# cannot show settings: {e}\n"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::register::RegisterOptions;

    #[test]
    fn defaults_written_as_toml_read_back_unchanged() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("settings.toml");
        let defaults = RegisterOptions::default();
        std::fs::write(&path, options_toml(&defaults)).unwrap();
        let back: RegisterOptions = load_options(&path).unwrap();
        assert_eq!(options_toml(&back), options_toml(&defaults));
    }

    #[test]
    fn a_partial_file_overrides_only_what_it_names() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("settings.json");
        std::fs::write(&path, r#"{"adaptive": {"iterations": "40x30x20"}}"#).unwrap();
        let got: RegisterOptions = load_options(&path).unwrap();
        assert_eq!(got.adaptive.iterations.to_string(), "40x30x20");
        assert_eq!(
            got.adaptive.threshold,
            RegisterOptions::default().adaptive.threshold
        );
        assert!(got.initialise);
    }

    #[test]
    fn unknown_keys_and_bad_values_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("typo.toml");
        for text in [
            "[adaptive]\niteratoins = 3\n",
            "[adaptive]\niterations = \"3xx\"\n",
        ] {
            std::fs::write(&path, text).unwrap();
            let err = load_options::<RegisterOptions>(&path)
                .unwrap_err()
                .to_string();
            assert!(err.contains("typo.toml"), "{err}");
        }
        let err = load_options::<RegisterOptions>(&dir.path().join("settings.yaml"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("settings.yaml"), "{err}");
    }
}
