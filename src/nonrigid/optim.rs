//! A small L-BFGS minimiser with a backtracking (Armijo) line search, for the few hundred
//! control-point displacements of the non-rigid stage. Written here because the well-kept
//! crates that offer it (argmin) bring a framework of traits and dependencies for a forty-line
//! loop; this one is deterministic and allocation-light.

/// Result of a minimisation.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Minimised {
    /// Final parameters.
    pub x: Vec<f64>,
    /// Cost at x.
    pub cost: f64,
    /// Cost at the start.
    pub start_cost: f64,
    /// Iterations (accepted steps).
    pub iterations: usize,
    /// Cost evaluations.
    pub evaluations: usize,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Minimises `f` (returning cost and gradient) from `x0`; stops after `max_iterations`, or when
/// an accepted step after the first lowers the cost by less than `tolerance` (relative).
pub fn lbfgs<E>(
    mut f: impl FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
    x0: Vec<f64>,
    max_iterations: usize,
    tolerance: f64,
) -> Result<Minimised, E> {
    const MEMORY: usize = 7;
    let mut x = x0;
    let (mut cost, mut grad) = f(&x)?;
    let start_cost = cost;
    let mut evaluations = 1;
    let mut history: Vec<Pair> = Vec::new();
    let mut iterations = 0;
    while iterations < max_iterations && !x.is_empty() {
        let mut d = direction(&grad, &history);
        let mut slope = dot(&grad, &d);
        if slope >= 0.0 {
            // Not a descent direction: restart from steepest descent.
            history.clear();
            let scale = 1.0 / dot(&grad, &grad).sqrt().max(1e-12);
            d = grad.iter().map(|g| -g * scale).collect();
            slope = dot(&grad, &d);
        }
        let mut step = 1.0;
        let mut accepted = None;
        for _ in 0..20 {
            let trial: Vec<f64> = x.iter().zip(&d).map(|(xi, di)| xi + step * di).collect();
            let (c, g) = f(&trial)?;
            evaluations += 1;
            if c <= cost + 1e-4 * step * slope {
                accepted = Some((trial, c, g));
                break;
            }
            step *= 0.5;
        }
        let Some((trial, c, g)) = accepted else { break };
        let s: Vec<f64> = trial.iter().zip(&x).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = g.iter().zip(&grad).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        if sy > 1e-12 {
            history.push((s, y, 1.0 / sy));
            if history.len() > MEMORY {
                history.remove(0);
            }
        }
        let decrease = (cost - c) / cost.abs().max(1e-300);
        x = trial;
        cost = c;
        grad = g;
        iterations += 1;
        // The first step is steepest descent at an arbitrary length (1 in x's norm, halved
        // until it lowers the cost), so its small decrease says nothing of convergence: on
        // the knee at 2 mm 90° one such step ended a whole refinement after a 1e-6 decrease.
        if decrease < tolerance && iterations > 1 {
            break;
        }
    }
    Ok(Minimised {
        x,
        cost,
        start_cost,
        iterations,
        evaluations,
    })
}

/// One remembered step of L-BFGS: s (the step), y (the gradient's change), 1 / (s·y).
type Pair = (Vec<f64>, Vec<f64>, f64);

/// The search direction d = −H g by the two-loop recursion over the remembered steps.
fn direction(grad: &[f64], history: &[Pair]) -> Vec<f64> {
    let mut q = grad.to_vec();
    let mut alphas = Vec::with_capacity(history.len());
    for (s, y, rho) in history.iter().rev() {
        let a = rho * dot(s, &q);
        q.iter_mut().zip(y).for_each(|(qi, yi)| *qi -= a * yi);
        alphas.push(a);
    }
    let gamma = history
        .last()
        .map(|(s, y, _)| dot(s, y) / dot(y, y))
        .unwrap_or_else(|| 1.0 / dot(grad, grad).sqrt().max(1e-12));
    q.iter_mut().for_each(|v| *v *= gamma);
    for ((s, y, rho), a) in history.iter().zip(alphas.iter().rev()) {
        let b = rho * dot(y, &q);
        q.iter_mut().zip(s).for_each(|(qi, si)| *qi += (a - b) * si);
    }
    q.iter().map(|v| -v).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_first_step_does_not_end_the_minimisation() {
        // From x = 10⁴ the first step (length 1) lowers x² by 2·10⁻⁴ of itself, under the
        // tolerance; the second, with curvature known, lands on the minimum.
        let f = |x: &[f64]| -> Result<(f64, Vec<f64>), ()> { Ok((x[0] * x[0], vec![2.0 * x[0]])) };
        let r = lbfgs(f, vec![1e4], 50, 1e-3).unwrap();
        assert!(r.x[0].abs() < 1e-6 && r.iterations >= 2, "{r:?}");
    }

    #[test]
    fn minimises_a_rosenbrock_valley() {
        let f = |x: &[f64]| -> Result<(f64, Vec<f64>), ()> {
            let (a, b) = (x[0], x[1]);
            let cost = (1.0 - a).powi(2) + 100.0 * (b - a * a).powi(2);
            let g = vec![
                -2.0 * (1.0 - a) - 400.0 * a * (b - a * a),
                200.0 * (b - a * a),
            ];
            Ok((cost, g))
        };
        let r = lbfgs(f, vec![-1.2, 1.0], 200, 0.0).unwrap();
        assert!(
            (r.x[0] - 1.0).abs() < 1e-4 && (r.x[1] - 1.0).abs() < 1e-4,
            "{:?}",
            r.x
        );
    }
}
