//! Quadratic smoothness energies of a warp sampled on a lattice, with their gradients.
//!
//! Membrane (Dirichlet) energy: the mean over lattice edges of the squared finite-difference
//! derivative |R(n + e_a) − R(n)|² / h_a². It is zero for a translation and charges every
//! stretch, shear and turn in proportion to its square, so the optimiser only deforms tissue
//! where the image evidence pays for it. Without it, SSD leaves the warp free wherever the image
//! is uniform along a direction (a limb's muscle and fat along its length), and the cubic RBF's
//! global support fills that freedom with drift.
//!
//! Bending energy (thin-plate): the mean squared second derivative, Σ_a |∂²R/∂a²|² +
//! 2 Σ_{a<b} |∂²R/∂a∂b|². It is zero for any affine warp, so it does not resist a limb turning as
//! a whole; it charges the *change* of motion across space, which is where drift differs from a
//! joint's motion.

use nalgebra::Vector3;

/// A linear finite-difference operator on the lattice: its taps (node offset, coefficient) and
/// the weight of its squared result in the energy.
struct Operator {
    taps: Vec<([isize; 3], f64)>,
    weight: f64,
}

/// Unit offset along `axis`, scaled by `by`.
fn along(axis: usize, by: isize) -> [isize; 3] {
    let mut o = [0; 3];
    o[axis] = by;
    o
}

/// The energy of `values` (one per lattice node, x fastest) on a lattice of `dims` nodes: the
/// mean, over every placement of every operator whose taps all fall on the lattice, of the
/// operator's weighted squared result; and its gradient with respect to each node's value.
fn quadratic_energy(
    values: &[Vector3<f64>],
    dims: [usize; 3],
    operators: &[Operator],
) -> (f64, Vec<Vector3<f64>>) {
    let mut energy = 0.0;
    let mut gradient = vec![Vector3::zeros(); values.len()];
    let mut placements = 0usize;
    let mut nodes = Vec::new();
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let at = [i as isize, j as isize, k as isize];
                for op in operators {
                    nodes.clear();
                    for (offset, _) in &op.taps {
                        let q: [isize; 3] = std::array::from_fn(|a| at[a] + offset[a]);
                        if (0..3).any(|a| q[a] < 0 || q[a] >= dims[a] as isize) {
                            break;
                        }
                        nodes.push(
                            q[0] as usize + dims[0] * (q[1] as usize + dims[1] * q[2] as usize),
                        );
                    }
                    if nodes.len() < op.taps.len() {
                        continue;
                    }
                    let result: Vector3<f64> = nodes
                        .iter()
                        .zip(&op.taps)
                        .map(|(&n, (_, c))| *c * values[n])
                        .sum();
                    energy += op.weight * result.norm_squared();
                    for (&n, (_, c)) in nodes.iter().zip(&op.taps) {
                        gradient[n] += 2.0 * op.weight * *c * result;
                    }
                    placements += 1;
                }
            }
        }
    }
    let scale = 1.0 / placements.max(1) as f64;
    gradient.iter_mut().for_each(|g| *g *= scale);
    (energy * scale, gradient)
}

/// Membrane energy (see the module's text) of `values` on a lattice of `dims` nodes spaced
/// `spacing_mm` apart, and its gradient with respect to each node's value.
pub fn membrane(
    values: &[Vector3<f64>],
    dims: [usize; 3],
    spacing_mm: [f64; 3],
) -> (f64, Vec<Vector3<f64>>) {
    let operators: Vec<Operator> = (0..3)
        .map(|a| Operator {
            taps: vec![
                ([0; 3], -1.0 / spacing_mm[a]),
                (along(a, 1), 1.0 / spacing_mm[a]),
            ],
            weight: 1.0,
        })
        .collect();
    quadratic_energy(values, dims, &operators)
}

/// Bending energy (see the module's text, in mm⁻²) of `values` on a lattice of `dims` nodes
/// spaced `spacing_mm` apart, and its gradient with respect to each node's value.
pub fn bending(
    values: &[Vector3<f64>],
    dims: [usize; 3],
    spacing_mm: [f64; 3],
) -> (f64, Vec<Vector3<f64>>) {
    let mut operators: Vec<Operator> = (0..3)
        .map(|a| {
            let c = 1.0 / (spacing_mm[a] * spacing_mm[a]);
            Operator {
                taps: vec![(along(a, -1), c), ([0; 3], -2.0 * c), (along(a, 1), c)],
                weight: 1.0,
            }
        })
        .collect();
    for a in 0..3 {
        for b in a + 1..3 {
            let c = 1.0 / (4.0 * spacing_mm[a] * spacing_mm[b]);
            let corner = |sa: isize, sb: isize| {
                let mut o = along(a, sa);
                o[b] = sb;
                (o, c * (sa * sb) as f64)
            };
            operators.push(Operator {
                taps: vec![corner(1, 1), corner(1, -1), corner(-1, 1), corner(-1, -1)],
                weight: 2.0,
            });
        }
    }
    quadratic_energy(values, dims, &operators)
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
    fn affine_warps_bend_nothing_and_quadratics_bend_by_their_second_derivative() {
        let affine = lattice(|p| {
            Vector3::new(
                0.3 * p[0] - 0.2 * p[1] + 4.0,
                0.1 * p[2],
                p[0] + p[1] + p[2],
            )
        });
        assert!(bending(&affine, DIMS, SPACING).0.abs() < 1e-20);
        // Placements per operator: the second difference along a needs 3 nodes on axis a; the
        // mixed one along a and b needs 3 on each.
        let placements = |axes: &[usize]| -> usize {
            (0..3)
                .map(|a| {
                    if axes.contains(&a) {
                        DIMS[a] - 2
                    } else {
                        DIMS[a]
                    }
                })
                .product()
        };
        let total = placements(&[0])
            + placements(&[1])
            + placements(&[2])
            + placements(&[0, 1])
            + placements(&[0, 2])
            + placements(&[1, 2]);
        // R = (0.05 x², 0, 0): ∂²R/∂x² = 0.1 wherever the x operator lands, nothing else.
        let along_x = lattice(|p| Vector3::new(0.05 * p[0] * p[0], 0.0, 0.0));
        let expected = 0.01 * placements(&[0]) as f64 / total as f64;
        assert!((bending(&along_x, DIMS, SPACING).0 - expected).abs() < 1e-12);
        // R = (0, 0.2 x z, 0): ∂²R/∂x∂z = 0.2, counted twice.
        let twisted = lattice(|p| Vector3::new(0.0, 0.2 * p[0] * p[2], 0.0));
        let expected = 2.0 * 0.04 * placements(&[0, 2]) as f64 / total as f64;
        assert!((bending(&twisted, DIMS, SPACING).0 - expected).abs() < 1e-12);
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
        for energy in [membrane, bending] {
            let (_, gradient) = energy(&values, DIMS, SPACING);
            let step = 1e-6;
            for n in [0, 7, 23, 31, values.len() - 1] {
                for c in 0..3 {
                    let mut plus = values.clone();
                    let mut minus = values.clone();
                    plus[n][c] += step;
                    minus[n][c] -= step;
                    let numeric = (energy(&plus, DIMS, SPACING).0
                        - energy(&minus, DIMS, SPACING).0)
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
}
