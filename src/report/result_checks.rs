//! The checks a finished registration is held to, so that a poor result is said out loud
//! rather than written silently: the final field does not fold, the warped source matches the
//! target better than the source did, every bone's motion lies inside the range its rotation
//! search covered, and no bone's motion is implausible, weakly determined or barely seen. `register` reports them in report.json under `checks` and on
//! stderr; `--strict` turns a failed check into a non-zero exit (the outputs are still
//! written, atomically, for inspection).

use crate::init::articulated::Initialisation;
use crate::joints::chain;
use crate::joints::confidence::Decision;
use crate::joints::joint::degrees_between;
use crate::pipeline::register::{RegisterOptions, Registration};

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
                "{:.4}% of the target's voxels have Jacobian determinant <= 0 (minimum {:.3}); \
                 {:.4}% more at bone contacts, where two bones slide on each other",
                100.0 * result.folded_share,
                result.min_jacobian,
                100.0 * result.contact_share
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
        checks.push(bones_confident(init));
    }
    checks
}

/// Every searched bone turns, relative to its parent, by no more than its search covered (its
/// largest angle plus the tilt of the search axis), and no bone's best candidate sits at the
/// edge of its searched range, where the true motion may lie beyond it.
fn bones_within_search(init: &Initialisation, options: &RegisterOptions) -> Check {
    let tilt = options.init.search_tilt_degrees;
    let motion_of = |code: u16| init.motions.iter().find(|m| m.0 == code).map(|m| m.1);
    let mut problems = Vec::new();
    for report in &init.reports {
        let link = chain::link(&options.init.chain, report.label);
        let (Some([from, to, step]), Some(parent)) = (
            link.and_then(|l| l.search_degrees),
            chain::parent_among(&options.init.chain, report.label, &init.bones),
        ) else {
            continue;
        };
        let limit = from.abs().max(to.abs()) + tilt;
        if let (Some(m), Some(p)) = (motion_of(report.label), motion_of(parent)) {
            let turn = degrees_between(&p, &m);
            if turn > limit {
                problems.push(format!(
                    "{} (label {}) turned {turn:.1}° from its parent, beyond the {limit:.0}° searched",
                    report.name, report.label
                ));
            }
        }
        // The search's last candidate: `to` itself only when the step divides the range.
        let last = from + ((to - from) / step + 1e-9).floor() * step;
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
            true => format!("every searched bone within its range of its parent (tilt {tilt:.0}°)"),
            false => problems.join("; "),
        },
    }
}

/// No bone's registration raised a doubt: none implausible and followed its parent instead,
/// weakly determined or barely seen (crate::joints::confidence). Which bones followed their parent is
/// said either way.
fn bones_confident(init: &Initialisation) -> Check {
    let warnings: Vec<&str> = init
        .reports
        .iter()
        .flat_map(|r| r.confidence.warnings.iter().map(String::as_str))
        .collect();
    let followed: Vec<String> = init
        .reports
        .iter()
        .filter(|r| r.confidence.decision == Decision::FollowedParent)
        .map(|r| format!("{} followed its parent ({})", r.name, r.confidence.reason))
        .collect();
    let mut detail = match warnings.is_empty() {
        true => "every bone's motion plausible and determined".to_string(),
        false => warnings.join("; "),
    };
    if !followed.is_empty() {
        detail = format!("{detail}; {}", followed.join("; "));
    }
    Check {
        name: "bones_confident",
        passed: warnings.is_empty(),
        detail,
    }
}
