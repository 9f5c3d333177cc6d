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
//!
//! Both are sums of quadratic operators placed wherever their taps fall on the lattice; the
//! lattice_energy kernel evaluates them with the cost (tests/reference.rs checks them against
//! closed forms and finite differences). Each term is the mean over its placements.

use crate::abi::{EnergyParams, Operator};

/// Unit offset along `axis`, scaled by `by`.
fn along(axis: usize, by: i32) -> [i32; 3] {
    let mut o = [0; 3];
    o[axis] = by;
    o
}

/// The membrane's operators: the first difference along each axis, per mm.
pub fn membrane(spacing_mm: [f64; 3]) -> Vec<Operator> {
    (0..3)
        .map(|a| {
            let c = (1.0 / spacing_mm[a]) as f32;
            Operator {
                taps: vec![([0; 3], -c), (along(a, 1), c)],
                weight: 1.0,
            }
        })
        .collect()
}

/// The bending energy's operators: the second difference along each axis and the mixed ones
/// (counted twice), per mm².
pub fn bending(spacing_mm: [f64; 3]) -> Vec<Operator> {
    let mut operators: Vec<Operator> = (0..3)
        .map(|a| {
            let c = (1.0 / (spacing_mm[a] * spacing_mm[a])) as f32;
            Operator {
                taps: vec![(along(a, -1), c), ([0; 3], -2.0 * c), (along(a, 1), c)],
                weight: 1.0,
            }
        })
        .collect();
    for a in 0..3 {
        for b in a + 1..3 {
            let c = (1.0 / (4.0 * spacing_mm[a] * spacing_mm[b])) as f32;
            let corner = |sa: i32, sb: i32| {
                let mut o = along(a, sa);
                o[b] = sb;
                (o, c * (sa * sb) as f32)
            };
            operators.push(Operator {
                taps: vec![corner(1, 1), corner(1, -1), corner(-1, 1), corner(-1, -1)],
                weight: 2.0,
            });
        }
    }
    operators
}

/// Placements of `op` whose taps all fall on a lattice of `dims` nodes.
pub fn placements(op: &Operator, dims: [usize; 3]) -> usize {
    (0..3)
        .map(|a| {
            let lo = op.taps.iter().map(|(o, _)| o[a]).min().unwrap_or(0);
            let hi = op.taps.iter().map(|(o, _)| o[a]).max().unwrap_or(0);
            dims[a].saturating_sub((hi - lo) as usize)
        })
        .product()
}

/// The terms of `energy` (weighted `weight`), each operator's weight divided by the placements
/// of the whole term, so the term is its mean over placements.
fn weighted(energy: Vec<Operator>, weight: f64, dims: [usize; 3]) -> Vec<Operator> {
    let total: usize = energy.iter().map(|op| placements(op, dims)).sum();
    energy
        .into_iter()
        .map(|op| Operator {
            weight: (weight * op.weight as f64 / total.max(1) as f64) as f32,
            taps: op.taps,
        })
        .collect()
}

/// Parameters of the lattice_energy kernel on a lattice of `dims` nodes `spacing_mm` apart:
/// the membrane weighted `membrane_weight`, the bending energy `bending_weight` (terms of weight
/// 0 left out), splatted image gradients scaled by `scale`.
pub fn energy_params(
    dims: [usize; 3],
    spacing_mm: [f64; 3],
    membrane_weight: f64,
    bending_weight: f64,
    scale: f32,
) -> EnergyParams {
    let mut operators = Vec::new();
    if membrane_weight > 0.0 {
        operators.extend(weighted(membrane(spacing_mm), membrane_weight, dims));
    }
    if bending_weight > 0.0 {
        operators.extend(weighted(bending(spacing_mm), bending_weight, dims));
    }
    EnergyParams::new(dims, scale, &operators)
}
