//! The checks a finished registration is held to, so that a poor result is said out loud
//! rather than written silently: the final field does not fold, the warped source matches the
//! target better than the source did, and every bone's motion lies inside the range its
//! rotation search covered. `register` reports them in report.json under `checks` and on
//! stderr; `--strict` turns a failed check into a non-zero exit (the outputs are still
//! written, atomically, for inspection).

use crate::articulated::{bone_name, Initialisation};
use crate::joint::rotation_degrees;
use crate::register::{RegisterOptions, Registration};

/// One check's outcome.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Check {
    /// Short name.
    pub name: &'static str,
    /// Whether the result passed.
    pub passed: bool,
    /// The figures behind the verdict.
    pub detail: String,
}

/// Correlation over the target's body, of the source resampled without and with the field.
#[derive(Clone, Copy, Debug)]
pub struct Correlations {
    /// The source resampled onto the target grid as it lies.
    pub before: f64,
    /// The warped source.
    pub after: f64,
}

/// All checks of a registration.
pub fn result_checks(
    result: &Registration,
    correlations: Correlations,
    options: &RegisterOptions,
) -> Vec<Check> {
    let mut checks = vec![
        Check {
            name: "field_does_not_fold",
            passed: result.folded_share == 0.0,
            detail: format!(
                "{:.4}% of the target's voxels have Jacobian determinant <= 0 (minimum {:.3})",
                100.0 * result.folded_share,
                result.min_jacobian
            ),
        },
        Check {
            name: "correlation_improves",
            passed: correlations.after >= correlations.before,
            detail: format!(
                "correlation with the target over its body {:.4} before, {:.4} after",
                correlations.before, correlations.after
            ),
        },
    ];
    if let Some(init) = &result.init {
        checks.push(bones_within_search(init, options));
    }
    checks
}

/// Every bone turns, relative to the reference bone, by no more than the search covered (its
/// largest angle plus the tilt of the search axis), and no bone's best candidate sits at the
/// edge of the searched range, where the true motion may lie beyond it.
fn bones_within_search(init: &Initialisation, options: &RegisterOptions) -> Check {
    let [from, to, step] = options.init.search_degrees;
    // The search's last candidate: `to` itself only when the step divides the range.
    let last = from + ((to - from) / step + 1e-9).floor() * step;
    let limit = from.abs().max(to.abs()) + options.init.search_tilt_degrees;
    let reference = init
        .motions
        .iter()
        .find(|(code, _)| *code == options.init.reference)
        .map(|(_, m)| *m)
        .unwrap_or_else(crate::volume::Affine::identity);
    let inverse = reference
        .try_inverse()
        .unwrap_or_else(crate::volume::Affine::identity);
    let mut problems = Vec::new();
    for (code, motion) in &init.motions {
        let turn = rotation_degrees(&(inverse * motion));
        if turn > limit {
            problems.push(format!(
                "{} (label {code}) turned {turn:.1}°, beyond the {limit:.0}° searched",
                bone_name(*code)
            ));
        }
    }
    for report in &init.reports {
        if let Some(best) = report.search_degrees {
            if best <= from + 1e-9 || best >= last - 1e-9 {
                problems.push(format!(
                    "{}'s best search candidate {best:.0}° is at the edge of the range {from:.0}..{last:.0}°",
                    report.name
                ));
            }
        }
    }
    Check {
        name: "bones_within_search",
        passed: problems.is_empty(),
        detail: match problems.is_empty() {
            true => format!(
                "every bone within {from:.0}..{to:.0}° of the reference (tilt {:.0}°)",
                options.init.search_tilt_degrees
            ),
            false => problems.join("; "),
        },
    }
}
