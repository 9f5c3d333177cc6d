//! Settings that vary by pyramid level, written coarse to fine in the registration community's
//! style (ANTs, elastix): `30x20x10` is 30 at the coarsest level and 10 at the finest; a single
//! value holds at every level.

use crate::error::{Error, Result};
use serde::{de, Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;
use std::str::FromStr;

/// Most pyramid levels a setting may ask for (the initialisation's and the non-rigid stage's).
pub const MAX_LEVELS: usize = 8;

/// One value per pyramid level, coarse to fine (or one value for all levels).
#[derive(Clone, Debug, PartialEq)]
pub struct PerLevel<T>(Vec<T>);

impl<T: Copy> PerLevel<T> {
    /// The same value at every level.
    pub fn all(value: T) -> Self {
        PerLevel(vec![value])
    }

    /// Values coarse to fine; at least one.
    pub fn coarse_to_fine(values: Vec<T>) -> Result<Self> {
        if values.is_empty() {
            return Err(Error::InvalidInput(
                "a per-level setting needs at least one value".into(),
            ));
        }
        Ok(PerLevel(values))
    }

    /// The value at pyramid level `level` counted from the finest (0): the last value is the
    /// finest level's, so a pyramid that came out shallower than asked for (a small image)
    /// uses the finer levels' values; levels beyond the list repeat its coarsest value.
    pub fn at_level(&self, level: usize) -> T {
        let n = self.0.len();
        self.0[n - 1 - level.min(n - 1)]
    }

    /// What `levels` levels read, written out coarse to fine (one value stays one): the
    /// setting as the stage ran it, for the report.
    pub fn for_levels(&self, levels: usize) -> Self {
        match self.0.len() {
            1 => self.clone(),
            _ => PerLevel((0..levels.max(1)).rev().map(|l| self.at_level(l)).collect()),
        }
    }

    /// The values, coarse to fine.
    pub fn values(&self) -> &[T] {
        &self.0
    }

    /// Checks the value count against the number of levels unless the value is the setting's
    /// own `default`, which reads for any level count through at_level (its finest values for
    /// fewer levels, its coarsest repeated for more): a file that changes only the number of
    /// levels runs the defaults' finest levels. A value written equal to the default counts as
    /// the default.
    pub fn check_given(&self, default: &Self, name: &str, levels: usize) -> Result<()>
    where
        T: fmt::Display + PartialEq,
    {
        match self == default {
            true => Ok(()),
            false => self.check(name, levels),
        }
    }

    /// Checks the value count against the number of levels (`name` names the setting).
    pub fn check(&self, name: &str, levels: usize) -> Result<()>
    where
        T: fmt::Display,
    {
        if self.0.len() == 1 || self.0.len() == levels {
            return Ok(());
        }
        let wanted = match levels {
            1 => "one value".to_string(),
            n => format!("one value or {n}"),
        };
        let plural = if levels == 1 { "" } else { "s" };
        Err(Error::InvalidInput(format!(
            "{name} has {} values ({self}) for {levels} pyramid level{plural}: give {wanted}",
            self.0.len()
        )))
    }
}

impl<T: fmt::Display> fmt::Display for PerLevel<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self.0.iter().map(|v| v.to_string()).collect();
        f.write_str(&parts.join("x"))
    }
}

impl<T: FromStr + Copy> FromStr for PerLevel<T>
where
    T::Err: fmt::Display,
{
    type Err = String;

    fn from_str(text: &str) -> std::result::Result<Self, String> {
        let values = text
            .split('x')
            .map(|part| {
                part.trim()
                    .parse::<T>()
                    .map_err(|e| format!("'{part}' in '{text}': {e}"))
            })
            .collect::<std::result::Result<Vec<T>, String>>()?;
        PerLevel::coarse_to_fine(values).map_err(|e| e.to_string())
    }
}

/// Writes one value as itself and several as `"30x20x10"`.
impl<T: fmt::Display + Serialize> Serialize for PerLevel<T> {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self.0.as_slice() {
            [one] => one.serialize(s),
            _ => s.serialize_str(&self.to_string()),
        }
    }
}

/// Accepts `"30x20x10"`, `[30, 20, 10]` or `30`.
impl<'de, T> Deserialize<'de> for PerLevel<T>
where
    T: FromStr + Copy + Deserialize<'de>,
    T::Err: fmt::Display,
{
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Written<T> {
            Text(String),
            List(Vec<T>),
            One(T),
        }
        // The untagged enum's own error names the enum ("did not match any variant of
        // untagged enum Written"), which tells a user nothing.
        let written = Written::<T>::deserialize(d).map_err(|_| {
            de::Error::custom(
                "expected one value for every level, a list coarse to fine, or text such as \"40x30x20\"",
            )
        })?;
        match written {
            Written::Text(text) => text.parse().map_err(de::Error::custom),
            Written::List(values) => PerLevel::coarse_to_fine(values).map_err(de::Error::custom),
            Written::One(value) => Ok(PerLevel::all(value)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_value_is_the_finest_levels() {
        let p: PerLevel<usize> = "40x30x20".parse().unwrap();
        assert_eq!([p.at_level(2), p.at_level(1), p.at_level(0)], [40, 30, 20]);
        assert_eq!(
            p.at_level(5),
            40,
            "levels beyond the list use the coarsest value"
        );
        assert_eq!(PerLevel::all(7).at_level(3), 7);
        assert!(p.check("iterations", 3).is_ok());
        let err = p.check("iterations", 4).unwrap_err().to_string();
        assert!(
            err.contains("40x30x20") && err.contains("4 pyramid levels"),
            "{err}"
        );
    }

    #[test]
    fn a_default_fits_any_level_count_and_another_value_its_own() {
        let default: PerLevel<usize> = "100x60x30".parse().unwrap();
        for levels in 1..=MAX_LEVELS {
            assert!(default.check_given(&default, "iterations", levels).is_ok());
        }
        let given: PerLevel<usize> = "50x40x20".parse().unwrap();
        assert!(given.check_given(&default, "iterations", 3).is_ok());
        let err = given.check_given(&default, "iterations", 2).unwrap_err();
        assert!(err.to_string().contains("iterations has 3 values"), "{err}");
        assert!(PerLevel::all(9)
            .check_given(&default, "iterations", 2)
            .is_ok());
        let run = |levels| default.for_levels(levels).to_string();
        assert_eq!([run(1), run(2), run(3)], ["30", "60x30", "100x60x30"]);
        assert_eq!(
            run(4),
            "100x100x60x30",
            "a fourth level repeats the coarsest"
        );
        assert_eq!(PerLevel::all(9).for_levels(3).to_string(), "9");
    }

    #[test]
    fn reads_text_lists_and_single_numbers_and_writes_text() {
        #[derive(Deserialize, Serialize)]
        struct S {
            v: PerLevel<f64>,
        }
        for (json, want) in [
            (r#"{"v":"8x4.5x2"}"#, vec![8.0, 4.5, 2.0]),
            (r#"{"v":[8,4.5,2]}"#, vec![8.0, 4.5, 2.0]),
            (r#"{"v":3}"#, vec![3.0]),
        ] {
            let s: S = serde_json::from_str(json).unwrap();
            assert_eq!(s.v.0, want, "{json}");
        }
        let s: S = serde_json::from_str(r#"{"v":[8,4.5,2]}"#).unwrap();
        assert_eq!(serde_json::to_string(&s).unwrap(), r#"{"v":"8x4.5x2"}"#);
        let one = S {
            v: PerLevel::all(3.5),
        };
        assert_eq!(serde_json::to_string(&one).unwrap(), r#"{"v":3.5}"#);
        assert!("8xx2".parse::<PerLevel<f64>>().is_err());
        assert!(serde_json::from_str::<S>(r#"{"v":[]}"#).is_err());
    }
}
