//! Tests the settings checks share, written so that NaN fails them (every comparison with NaN
//! is false).

/// 0 ≤ v < ∞, false for NaN.
pub fn finite_non_negative(v: f64) -> bool {
    v.is_finite() && v >= 0.0
}

/// lo ≤ v ≤ hi, false for NaN.
pub fn within(v: f64, lo: f64, hi: f64) -> bool {
    v >= lo && v <= hi
}
