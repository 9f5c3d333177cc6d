//! The cubic radial-basis warp of the non-rigid stage (paper eq. 4):
//! R(x) = a₀ + a₁x + a₂y + a₃z + Σᵢ λᵢ φ(|x − cᵢ|), φ(r) = r³, per component, world mm.
//!
//! The paper calls φ(r) = r³ a thin plate spline; in 3-D it is the cubic (triharmonic) radial
//! basis (elastix's VolumeSpline). Coefficients interpolate given displacements fᵢ at the
//! control points cᵢ by solving [Φ + μI  P; Pᵀ 0] [λ; a] = [f; 0] in f64 (μ ≥ 0 smooths instead
//! of interpolating). The matrix depends on the control points only, so it is factored once per
//! set of points and reused for every set of displacements and for mapping gradients back.

use crate::error::{Error, Result};
use nalgebra::{DMatrix, DVector, Vector3};

/// φ(r) = r³.
pub fn phi(r: f64) -> f64 {
    r * r * r
}

/// A factored interpolation system for a fixed set of control points.
pub struct RbfSystem {
    /// Control points (world mm).
    pub centres: Vec<Vector3<f64>>,
    /// Polynomial terms used: 4 (affine) when the points span 3-D, else 1 (constant).
    pub poly: usize,
    lu: nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>,
}

/// Solved coefficients, per component.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RbfCoefficients {
    /// λ per control point (mm per mm³).
    pub lambda: Vec<[f64; 3]>,
    /// a₀ … a₃ per component (the affine part; zero beyond `poly`).
    pub affine: [[f64; 3]; 4],
}

fn poly_terms(x: &Vector3<f64>, poly: usize) -> [f64; 4] {
    let all = [1.0, x.x, x.y, x.z];
    std::array::from_fn(|k| if k < poly { all[k] } else { 0.0 })
}

/// True when the points span three dimensions (an affine part is determined).
fn spans_3d(centres: &[Vector3<f64>]) -> bool {
    if centres.len() < 4 {
        return false;
    }
    let c = centres.iter().sum::<Vector3<f64>>() / centres.len() as f64;
    let mut cov = nalgebra::Matrix3::zeros();
    for p in centres {
        cov += (p - c) * (p - c).transpose();
    }
    let ev = cov.symmetric_eigen().eigenvalues;
    let max = ev.max();
    max > 0.0 && ev.min() > 1e-9 * max
}

impl RbfSystem {
    /// Factors the system for `centres` with smoothing `mu` (0 interpolates). Fewer than four
    /// points, or coplanar ones, keep only a constant term; duplicate points are refused.
    pub fn new(centres: Vec<Vector3<f64>>, mu: f64) -> Result<Self> {
        let n = centres.len();
        for i in 0..n {
            for j in 0..i {
                if (centres[i] - centres[j]).norm() < 1e-6 {
                    return Err(Error::InvalidInput(format!(
                        "control points {j} and {i} coincide at {:?}",
                        centres[i].as_slice()
                    )));
                }
            }
        }
        let poly = if spans_3d(&centres) {
            4
        } else if n > 0 {
            1
        } else {
            0
        };
        let size = n + poly;
        let mut a = DMatrix::zeros(size, size);
        for i in 0..n {
            for j in 0..n {
                a[(i, j)] = phi((centres[i] - centres[j]).norm()) + if i == j { mu } else { 0.0 };
            }
            let p = poly_terms(&centres[i], poly);
            for k in 0..poly {
                a[(i, n + k)] = p[k];
                a[(n + k, i)] = p[k];
            }
        }
        let lu = a.lu();
        if n > 0 && !lu.is_invertible() {
            return Err(Error::InvalidInput(
                "the control-point system is singular".into(),
            ));
        }
        Ok(RbfSystem { centres, poly, lu })
    }

    /// Number of control points.
    pub fn len(&self) -> usize {
        self.centres.len()
    }

    /// True without control points.
    pub fn is_empty(&self) -> bool {
        self.centres.is_empty()
    }

    fn solve_rhs(&self, rhs: [DVector<f64>; 3]) -> Result<[DVector<f64>; 3]> {
        if rhs[0].is_empty() {
            return Ok(rhs);
        }
        let out = rhs.map(|b| self.lu.solve(&b).unwrap_or_else(|| DVector::zeros(b.len())));
        if out.iter().any(|v| v.iter().any(|x| !x.is_finite())) {
            return Err(Error::InvalidInput(
                "the control-point system is ill-conditioned".into(),
            ));
        }
        Ok(out)
    }

    /// Coefficients interpolating `values` (one 3-vector per control point).
    pub fn coefficients(&self, values: &[Vector3<f64>]) -> Result<RbfCoefficients> {
        let n = self.len();
        let size = n + self.poly;
        let rhs: [DVector<f64>; 3] = std::array::from_fn(|c| {
            DVector::from_fn(size, |i, _| if i < n { values[i][c] } else { 0.0 })
        });
        let sol = self.solve_rhs(rhs)?;
        Ok(RbfCoefficients {
            lambda: (0..n).map(|i| [sol[0][i], sol[1][i], sol[2][i]]).collect(),
            affine: std::array::from_fn(|k| {
                std::array::from_fn(|c| if k < self.poly { sol[c][n + k] } else { 0.0 })
            }),
        })
    }

    /// Maps the cost's derivatives with respect to the coefficients — G_i = ∂E/∂λ_i (3-vector)
    /// and Q_k = ∂E/∂a_k — to derivatives with respect to the control-point values f: the
    /// system is symmetric, so ∂E/∂f = (A⁻¹ [G; Q]) restricted to the first n rows.
    pub fn value_gradient(
        &self,
        g: &[Vector3<f64>],
        q: &[Vector3<f64>; 4],
    ) -> Result<Vec<Vector3<f64>>> {
        let n = self.len();
        let size = n + self.poly;
        let rhs: [DVector<f64>; 3] = std::array::from_fn(|c| {
            DVector::from_fn(size, |i, _| if i < n { g[i][c] } else { q[i - n][c] })
        });
        let sol = self.solve_rhs(rhs)?;
        Ok((0..n)
            .map(|i| Vector3::new(sol[0][i], sol[1][i], sol[2][i]))
            .collect())
    }
}

impl RbfCoefficients {
    /// R at point x.
    pub fn eval(&self, centres: &[Vector3<f64>], x: &Vector3<f64>) -> Vector3<f64> {
        let mut r = Vector3::new(self.affine[0][0], self.affine[0][1], self.affine[0][2]);
        for k in 1..4 {
            r += Vector3::from(self.affine[k]) * x[k - 1];
        }
        for (c, l) in centres.iter().zip(&self.lambda) {
            r += Vector3::from(*l) * phi((x - c).norm());
        }
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_its_control_values_and_reproduces_affine_fields() {
        let centres: Vec<Vector3<f64>> = (0..12)
            .map(|i| {
                Vector3::new(
                    (i * 7 % 5) as f64 * 10.0,
                    (i * 3 % 4) as f64 * 8.0,
                    (i % 3) as f64 * 6.0 + i as f64,
                )
            })
            .collect();
        let affine = |x: &Vector3<f64>| {
            Vector3::new(1.0 + 0.1 * x.x, -2.0 + 0.05 * x.y - 0.02 * x.z, 0.3 * x.z)
        };
        let system = RbfSystem::new(centres.clone(), 0.0).unwrap();
        let values: Vec<_> = centres.iter().map(affine).collect();
        let coef = system.coefficients(&values).unwrap();
        // An affine field is reproduced exactly everywhere (λ = 0), not just at the points.
        for x in [Vector3::new(3.0, 4.0, 5.0), Vector3::new(-20.0, 50.0, 7.0)] {
            assert!((coef.eval(&centres, &x) - affine(&x)).norm() < 1e-8);
        }
        let bumpy: Vec<_> = centres
            .iter()
            .enumerate()
            .map(|(i, _)| Vector3::new(i as f64, 0.0, -(i as f64)))
            .collect();
        let coef = system.coefficients(&bumpy).unwrap();
        for (c, v) in centres.iter().zip(&bumpy) {
            assert!((coef.eval(&centres, c) - v).norm() < 1e-7);
        }
    }

    #[test]
    fn degenerate_point_sets_are_handled() {
        // Three points: constant polynomial only, still interpolating, no NaN.
        let few = vec![Vector3::zeros(), Vector3::x(), Vector3::y()];
        let s = RbfSystem::new(few.clone(), 0.0).unwrap();
        assert_eq!(s.poly, 1);
        let c = s
            .coefficients(&[Vector3::x(), Vector3::y(), Vector3::z()])
            .unwrap();
        assert!((c.eval(&few, &few[1]) - Vector3::y()).norm() < 1e-9);
        // Coplanar points: no affine part.
        let flat: Vec<_> = (0..6)
            .map(|i| Vector3::new(i as f64, (i * i) as f64, 0.0))
            .collect();
        assert_eq!(RbfSystem::new(flat, 0.0).unwrap().poly, 1);
        // Duplicates are refused.
        assert!(RbfSystem::new(vec![Vector3::zeros(), Vector3::zeros()], 0.0).is_err());
        // No points: an empty system.
        assert!(RbfSystem::new(Vec::new(), 0.0).unwrap().is_empty());
    }
}
