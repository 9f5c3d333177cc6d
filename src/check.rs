//! Tests the settings checks share, written so that NaN fails them (every comparison with NaN
//! is false).

/// v > 0, false for NaN.
pub fn positive(v: f64) -> bool {
    v > 0.0
}

/// v ≥ 0, false for NaN.
pub fn non_negative(v: f64) -> bool {
    v >= 0.0
}
