//! Membrane (Dirichlet) energy of a warp sampled on a lattice: the mean over lattice edges of
//! the squared finite-difference derivative |R(n + e_a) − R(n)|² / h_a². It is zero for a
//! translation and charges every stretch, shear and turn in proportion to its square, so the
//! optimiser only deforms tissue where the image evidence pays for it. Without it, SSD leaves
//! the warp free wherever the image is uniform along a direction (a limb's muscle and fat along
//! its length), and the cubic RBF's global support fills that freedom with drift.

use nalgebra::Vector3;

/// The energy of `values` (one per lattice node, x fastest) on a lattice of `dims` nodes spaced
/// `spacing_mm` apart, and its gradient with respect to each node's value.
pub fn membrane(
    values: &[Vector3<f64>],
    dims: [usize; 3],
    spacing_mm: [f64; 3],
) -> (f64, Vec<Vector3<f64>>) {
    let index = |i: usize, j: usize, k: usize| i + dims[0] * (j + dims[1] * k);
    let mut energy = 0.0;
    let mut gradient = vec![Vector3::zeros(); values.len()];
    let mut edges = 0usize;
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let n = index(i, j, k);
                let ahead = [
                    (i + 1 < dims[0]).then(|| index(i + 1, j, k)),
                    (j + 1 < dims[1]).then(|| index(i, j + 1, k)),
                    (k + 1 < dims[2]).then(|| index(i, j, k + 1)),
                ];
                for (axis, m) in ahead.into_iter().enumerate() {
                    let Some(m) = m else { continue };
                    let inverse_h2 = 1.0 / (spacing_mm[axis] * spacing_mm[axis]);
                    let difference = values[m] - values[n];
                    energy += difference.norm_squared() * inverse_h2;
                    gradient[m] += 2.0 * inverse_h2 * difference;
                    gradient[n] -= 2.0 * inverse_h2 * difference;
                    edges += 1;
                }
            }
        }
    }
    let scale = 1.0 / edges.max(1) as f64;
    gradient.iter_mut().for_each(|g| *g *= scale);
    (energy * scale, gradient)
}

#[cfg(test)]
mod tests {
    use super::*;

    const DIMS: [usize; 3] = [4, 5, 3];
    const SPACING: [f64; 3] = [2.0, 3.0, 5.0];

    fn lattice(f: impl Fn([f64; 3]) -> Vector3<f64>) -> Vec<Vector3<f64>> {
        (0..DIMS.iter().product::<usize>())
            .map(|n| {
                let ijk = [
                    n % DIMS[0],
                    (n / DIMS[0]) % DIMS[1],
                    n / (DIMS[0] * DIMS[1]),
                ];
                f(std::array::from_fn(|a| ijk[a] as f64 * SPACING[a]))
            })
            .collect()
    }

    #[test]
    fn translations_cost_nothing_and_a_uniform_stretch_costs_its_square() {
        let shift = lattice(|_| Vector3::new(3.0, -1.0, 7.0));
        assert_eq!(membrane(&shift, DIMS, SPACING).0, 0.0);
        // R = (0.1 x, 0, 0): only the x edges differ, each by 0.1 per mm.
        let stretch = lattice(|p| Vector3::new(0.1 * p[0], 0.0, 0.0));
        let x_edges = (DIMS[0] - 1) * DIMS[1] * DIMS[2];
        let all_edges =
            x_edges + DIMS[0] * (DIMS[1] - 1) * DIMS[2] + DIMS[0] * DIMS[1] * (DIMS[2] - 1);
        let expected = 0.01 * x_edges as f64 / all_edges as f64;
        assert!((membrane(&stretch, DIMS, SPACING).0 - expected).abs() < 1e-12);
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let values = lattice(|p| {
            Vector3::new(
                (0.3 * p[0]).sin() + 0.1 * p[2],
                (0.2 * p[1] * p[2]).cos(),
                0.05 * p[0] * p[1],
            )
        });
        let (_, gradient) = membrane(&values, DIMS, SPACING);
        let step = 1e-6;
        for n in [0, 7, 23, values.len() - 1] {
            for c in 0..3 {
                let mut plus = values.clone();
                let mut minus = values.clone();
                plus[n][c] += step;
                minus[n][c] -= step;
                let numeric = (membrane(&plus, DIMS, SPACING).0
                    - membrane(&minus, DIMS, SPACING).0)
                    / (2.0 * step);
                assert!(
                    (numeric - gradient[n][c]).abs() < 1e-7,
                    "node {n} component {c}: {numeric} vs {}",
                    gradient[n][c]
                );
            }
        }
    }
}
