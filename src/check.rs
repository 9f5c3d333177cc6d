//! Tests the settings checks share, written so that NaN fails them (every comparison with NaN
//! is false).

/// lo ≤ v ≤ hi, false for NaN.
pub fn within(v: f64, lo: f64, hi: f64) -> bool {
    v >= lo && v <= hi
}

/// One numeric setting and the range its values must lie in: a row of a stage's table of
/// checks ([`check_ranges`]).
pub struct Range<'a> {
    /// The setting's key within its section.
    pub name: &'a str,
    /// Its values (one per level for a per-level setting).
    pub values: Vec<f64>,
    /// The least and the most allowed, both included.
    pub bounds: (f64, f64),
    /// The unit as the message writes it after the range, e.g. " (mm)".
    pub unit: &'a str,
}

impl<'a> Range<'a> {
    /// A row of the table.
    pub fn new(name: &'a str, values: Vec<f64>, bounds: (f64, f64), unit: &'a str) -> Self {
        Range {
            name,
            values,
            bounds,
            unit,
        }
    }
}

/// An upper bound that only keeps a value finite: the row reads "at least lo".
pub const UNBOUNDED: f64 = f64::MAX;

/// Checks every row of a stage's table: each value within its row's bounds (NaN and infinity
/// never are), else an error naming `section.name` and the range.
pub fn check_ranges(section: &str, table: &[Range]) -> crate::error::Result<()> {
    for row in table {
        let (lo, hi) = row.bounds;
        if !row.values.iter().all(|&v| within(v, lo, hi)) {
            let range = match hi {
                UNBOUNDED => format!("finite and at least {lo}"),
                _ => format!("{lo} to {hi}"),
            };
            let key = match section {
                "" => row.name.to_string(),
                _ => format!("{section}.{}", row.name),
            };
            let unit = row.unit;
            return Err(crate::error::Error::InvalidInput(format!(
                "{key} must be {range}{unit}"
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_table_names_the_first_setting_out_of_its_range() {
        let table = [
            Range::new("gain", vec![1.0, 2.0], (0.0, UNBOUNDED), " (mm)"),
            Range::new("radius", vec![3.0], (1.0, 2.0), " (voxels)"),
        ];
        let err = check_ranges("stage", &table).unwrap_err().to_string();
        assert!(
            err.contains("stage.radius must be 1 to 2 (voxels)"),
            "{err}"
        );
        for bad in [f64::NAN, f64::INFINITY, -1.0] {
            let table = [Range::new("gain", vec![1.0, bad], (0.0, UNBOUNDED), "")];
            let err = check_ranges("", &table).unwrap_err().to_string();
            assert!(err.contains("gain must be finite and at least 0"), "{err}");
            assert!(!err.contains(".gain"), "{err}");
        }
        assert!(check_ranges("stage", &table[..1]).is_ok());
    }
}
