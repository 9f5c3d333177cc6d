//! Removing folds from an initial field: linear or dual-quaternion blending of bone motions
//! folds soft tissue where a bone turns farther than its weights' falloff is wide (above the
//! patella, behind the knee), and the pull-back of a folded blend has no consistent answer
//! there. Two steps, both leaving bones rigid: broad local smoothing, then a targeted push on
//! whatever smoothing could not undo (folds pinned by a bone). The push alone also serves a
//! registration's total field ([`unfold_registration`]) and the phantom's truth field.

use crate::backend::Backend;
use crate::error::Result;
use crate::volume::{Affine, Field, Grid, Labels, Volume};
use glam::Vec3;

/// Jacobian determinant below which a voxel counts as folded (or about to fold) for repair.
pub const FOLD_THRESHOLD: f32 = 0.05;
/// Inversion residual, as a share of the finest voxel spacing, below which a voxel mapped into a
/// bone moves with it (a solved pull-back of a bone voxel is exact to float precision).
const RIGID_RESIDUAL: f32 = 0.1;
/// Most repair rounds.
const REPAIR_ROUNDS: usize = 30;
/// Voxels around each folded voxel that are smoothed with it.
const REPAIR_MARGIN: usize = 2;

/// What [`repair_folds`] did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct FoldRepair {
    /// Voxels with det ≤ 0.05 before repair (bone voxels aside in an initial field's repair).
    pub folded_before: usize,
    /// Voxels with det ≤ 0.05 after both steps, bone voxels included.
    pub folded_after: usize,
    /// Rounds of local smoothing.
    pub rounds: usize,
    /// Steps of the targeted push.
    pub unfold_steps: usize,
}

/// Removes the folds of an initial field. First it smooths the displacement locally — the
/// voxels with det J ≤ 0.05 and two voxels around them, by 27-neighbour averaging — which
/// undoes most folds and keeps the field smooth; then [`unfold`] lifts what is left. Both leave
/// bone voxels untouched so bones stay rigid, and never move a soft-tissue voxel's source point
/// into a bone (that would grow the bone in the initialised source: at 60° the patella by 10%).
/// A bone voxel is one whose source point lies in one of the `bones` of `labels` *and* whose
/// blend was inverted (`residual`, mm, below [`RIGID_RESIDUAL`] of a voxel): where the blend
/// folds, the pull-back can stop inside a bone without solving it, and those voxels are
/// tissue caught in the fold (at 90° on the paper grid, a folded patch mapped into the
/// patella that nothing else could lift).
pub fn repair_folds<B: Backend>(
    backend: &B,
    field: &mut Field,
    residual: &Volume,
    labels: &Labels,
    bones: &[u16],
) -> Result<FoldRepair> {
    let [nx, ny, nz] = field.grid.dims;
    // The lookup keeps its own copy of the grid: the field is rewritten under it.
    let grid = field.grid.clone();
    let into_bone = BoneLookup::new(&grid, labels, bones);
    let solved = RIGID_RESIDUAL * grid.finest_spacing() as f32;
    let rigid: Vec<bool> = (0..grid.len())
        .map(|n| residual.data[n] <= solved && into_bone.at(n, field.data[n]))
        .collect();
    let mut report = FoldRepair::default();
    for round in 0..=REPAIR_ROUNDS {
        let det = backend.jacobian(field)?;
        let bad: Vec<usize> = (0..det.data.len())
            .filter(|&n| det.data[n] <= FOLD_THRESHOLD && !rigid[n])
            .collect();
        if round == 0 {
            report.folded_before = bad.len();
        }
        report.folded_after = bad.len();
        if bad.is_empty() || round == REPAIR_ROUNDS {
            break;
        }
        report.rounds = round + 1;
        let mut region = vec![false; det.data.len()];
        for &n in &bad {
            let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
            let (lo, hi) = (
                |c: usize| c.saturating_sub(REPAIR_MARGIN),
                |c: usize, n: usize| (c + REPAIR_MARGIN + 1).min(n),
            );
            for dk in lo(k)..hi(k, nz) {
                for dj in lo(j)..hi(j, ny) {
                    for di in lo(i)..hi(i, nx) {
                        let m = di + nx * (dj + ny * dk);
                        region[m] = !rigid[m];
                    }
                }
            }
        }
        for _ in 0..3 {
            let before = field.data.clone();
            for n in (0..region.len()).filter(|&n| region[n]) {
                let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
                let mut sum = [0.0f32; 3];
                let mut count = 0.0f32;
                for dk in k.saturating_sub(1)..(k + 2).min(nz) {
                    for dj in j.saturating_sub(1)..(j + 2).min(ny) {
                        for di in i.saturating_sub(1)..(i + 2).min(nx) {
                            let v = before[di + nx * (dj + ny * dk)];
                            for c in 0..3 {
                                sum[c] += v[c];
                            }
                            count += 1.0;
                        }
                    }
                }
                let smoothed = sum.map(|s| s / count);
                if !into_bone.at(n, smoothed) || into_bone.at(n, field.data[n]) {
                    field.data[n] = smoothed;
                }
            }
        }
    }
    (report.folded_after, report.unfold_steps) =
        unfold(backend, field, &rigid, &|n, u| into_bone.at(n, u))?;
    Ok(report)
}

/// Unfolds a registration's total field, whose Jacobian determinant is `det`: [`unfold`] with
/// the voxels whose source point lies in one of the `bones` of `labels` held, and no tissue
/// pushed into a bone. The adaptive warp is smooth and does not fold (its step control sees
/// to that), but composed with an initial field that is sharply compressed behind a bent knee it
/// can carry a few voxels past each other there.
pub fn unfold_registration<B: Backend>(
    backend: &B,
    field: &mut Field,
    det: &Volume,
    labels: &Labels,
    bones: &[u16],
) -> Result<FoldRepair> {
    let folded_before = det.data.iter().filter(|&&d| d <= FOLD_THRESHOLD).count();
    if folded_before as f64 > UNFOLD_MAX_SHARE * det.data.len() as f64 {
        // Not a fold to repair but a failed registration (an almost empty target once folded
        // 46% of the voxels, and unfolding took 150 s): left as it is for the checks to report.
        return Ok(FoldRepair {
            folded_before,
            folded_after: folded_before,
            rounds: 0,
            unfold_steps: 0,
        });
    }
    let rigid = maps_into_bone(field, labels, bones);
    // The lookup keeps its own copy of the grid: the field is rewritten under it.
    let grid = field.grid.clone();
    let into_bone = BoneLookup::new(&grid, labels, bones);
    let (folded_after, unfold_steps) = unfold(backend, field, &rigid, &|n, u| into_bone.at(n, u))?;
    Ok(FoldRepair {
        folded_before,
        folded_after,
        rounds: 0,
        unfold_steps,
    })
}

/// Share of folded voxels beyond which a field is not unfolded.
const UNFOLD_MAX_SHARE: f64 = 0.05;
/// Most unfolding steps.
const UNFOLD_STEPS: usize = 1000;

/// The determinant each folded voxel is pushed towards.
const UNFOLD_TARGET: f32 = 0.3;

/// Lifts every voxel of `field` with det J ≤ [`FOLD_THRESHOLD`]: each pushes its movable
/// neighbours' displacements along the gradient of its own Jacobian determinant, far enough to
/// lift it (linearised) to [`UNFOLD_TARGET`] — the folding correction NiftyReg applies to spline
/// grids, on a dense field. Smoothing cannot undo a fold pinned by a bone (beside a bone whose
/// voxels stay rigid the average pulls the tissue's source point into the bone); this can.
/// Voxels marked `rigid` never move, and no step carries a voxel's source point into a bone:
/// `in_bone(n, u)` says whether voxel n displaced by u lands in one. Returns the voxels still
/// folded and the steps taken.
pub fn unfold<B: Backend>(
    backend: &B,
    field: &mut Field,
    rigid: &[bool],
    in_bone: &(dyn Fn(usize, [f32; 3]) -> bool + Sync),
) -> Result<(usize, usize)> {
    let [nx, ny, nz] = field.grid.dims;
    let inv = field.grid.world_to_voxel_affine();
    // Row a: d(index a)/d(world mm).
    let index_per_mm: [Vec3; 3] = std::array::from_fn(|a| {
        Vec3::new(inv[(a, 0)] as f32, inv[(a, 1)] as f32, inv[(a, 2)] as f32)
    });
    let dims = [nx, ny, nz];
    let stride = [1, nx, nx * ny];
    // The neighbours the Jacobian kernel differences along axis a at voxel n, and the factor
    // on their difference: central inside, one-sided on the faces.
    let neighbours = |n: usize, a: usize| {
        let c = n / stride[a] % dims[a];
        let lo = if c > 0 { n - stride[a] } else { n };
        let hi = if c + 1 < dims[a] { n + stride[a] } else { n };
        let factor = if c > 0 && c + 1 < dims[a] { 0.5 } else { 1.0 };
        (lo, hi, factor)
    };
    let largest_step = field.grid.finest_spacing() as f32 / 4.0;
    // Tissue voxels that no fraction of the last step could move without entering a bone: the
    // next step leaves them and lifts the folds beside them by their other neighbours.
    let mut blocked = std::collections::BTreeSet::new();
    let u = |field: &Field, n: usize| Vec3::from_array(field.data[n]);
    // det J at voxel n from its stencil's differences, and ∂det/∂(column a of D).
    let determinant = |field: &Field, n: usize| {
        let d = [0, 1, 2].map(|a| {
            let (lo, hi, factor) = neighbours(n, a);
            (u(field, hi) - u(field, lo)) * factor
        });
        determinant_and_gradient(d, index_per_mm)
    };
    // The determinants are kept up to date locally: moving voxel q changes det J only at q
    // and its six neighbours (whose differences it enters).
    let mut det = backend.jacobian(field)?.data;
    // Folded voxels that map into a bone count too: they stay, their neighbours move.
    let mut bad: std::collections::BTreeSet<usize> = (0..det.len())
        .filter(|&n| det[n] <= FOLD_THRESHOLD)
        .collect();
    let mut steps = 0;
    while !bad.is_empty() && steps < UNFOLD_STEPS {
        // One sweep over the folded voxels in index order, each push applied at once so the
        // next voxel sees it (Gauss-Seidel: simultaneous pushes on a shared neighbour can
        // cancel and stall).
        let refused_before = std::mem::take(&mut blocked);
        let folded: Vec<usize> = bad.iter().copied().collect();
        for n in folded {
            let (now, g) = determinant(field, n);
            if now > FOLD_THRESHOLD {
                continue;
            }
            // ∂det/∂u at each neighbour in the stencil that may move.
            let movable: Vec<(usize, Vec3)> = (0..3)
                .flat_map(|a| {
                    let (lo, hi, factor) = neighbours(n, a);
                    [(hi, g[a] * factor), (lo, -g[a] * factor)]
                })
                .filter(|&(q, _)| {
                    q != n && !rigid[q] && !refused_before.contains(&q) && !blocked.contains(&q)
                })
                .collect();
            let norm: f32 = movable.iter().map(|(_, gq)| gq.length_squared()).sum();
            if norm <= f32::EPSILON {
                continue;
            }
            let s = (UNFOLD_TARGET - now) / norm;
            for (q, gq) in movable {
                let shift = (gq * s).clamp_length_max(largest_step);
                // Beside a bone the full step can carry the source point into it: take the
                // longest of 1, 1/2, 1/4, 1/8 of it that does not.
                let from = u(field, q);
                let Some(moved) = [1.0, 0.5, 0.25, 0.125]
                    .into_iter()
                    .map(|f| (from + shift * f).to_array())
                    .find(|&moved| !in_bone(q, moved) || in_bone(q, field.data[q]))
                else {
                    blocked.insert(q);
                    continue;
                };
                field.data[q] = moved;
                let mut touched = vec![q];
                for a in 0..3 {
                    let (lo, hi, _) = neighbours(q, a);
                    touched.extend([lo, hi]);
                }
                for v in touched {
                    det[v] = determinant(field, v).0;
                    if det[v] <= FOLD_THRESHOLD {
                        bad.insert(v);
                    } else {
                        bad.remove(&v);
                    }
                }
            }
        }
        steps += 1;
    }
    // The count reported is the Jacobian kernel's own.
    let det = backend.jacobian(field)?;
    let left = det.data.iter().filter(|&&d| d <= FOLD_THRESHOLD).count();
    Ok((left, steps))
}

/// det(I + D G) and its gradient with respect to each column of D, where column a of D is the
/// field's difference along index axis a (as the Jacobian kernel takes it) and row a of G is
/// d(index a)/d(world mm): d det = tr(adj(J) dD G), so ∂det/∂(column a) = cof(J) · G_a.
fn determinant_and_gradient(d: [Vec3; 3], g: [Vec3; 3]) -> (f32, [Vec3; 3]) {
    let rows: [Vec3; 3] =
        std::array::from_fn(|c| g[0] * d[0][c] + g[1] * d[1][c] + g[2] * d[2][c] + Vec3::AXES[c]);
    let cofactor = [
        rows[1].cross(rows[2]),
        rows[2].cross(rows[0]),
        rows[0].cross(rows[1]),
    ];
    let gradient = g.map(|ga| {
        Vec3::new(
            cofactor[0].dot(ga),
            cofactor[1].dot(ga),
            cofactor[2].dot(ga),
        )
    });
    (rows[0].dot(cofactor[0]), gradient)
}

/// Target voxels whose source point (p + u) lies in a bone of `labels` (nearest voxel).
pub fn maps_into_bone(field: &Field, labels: &Labels, bones: &[u16]) -> Vec<bool> {
    let lookup = BoneLookup::new(&field.grid, labels, bones);
    (0..field.grid.len())
        .map(|n| lookup.at(n, field.data[n]))
        .collect()
}

/// Whether target voxel n displaced by u lands in one of `bones` of the source `labels`.
struct BoneLookup<'a> {
    target: &'a Grid,
    labels: &'a Labels,
    bones: &'a [u16],
    to_label: Affine,
}

impl<'a> BoneLookup<'a> {
    fn new(target: &'a Grid, labels: &'a Labels, bones: &'a [u16]) -> Self {
        let to_label = labels.grid.world_to_voxel_affine();
        BoneLookup {
            target,
            labels,
            bones,
            to_label,
        }
    }

    fn at(&self, n: usize, u: [f32; 3]) -> bool {
        let w = self.target.world_of(n);
        let q = self.to_label
            * nalgebra::Vector4::new(
                w[0] + u[0] as f64,
                w[1] + u[1] as f64,
                w[2] + u[2] as f64,
                1.0,
            );
        let ijk = [q.x, q.y, q.z].map(|v| v.round());
        let dims = self.labels.grid.dims;
        if (0..3).any(|a| ijk[a] < 0.0 || ijk[a] >= dims[a] as f64) {
            return false;
        }
        let label = self.labels.data[self.labels.grid.index(
            ijk[0] as usize,
            ijk[1] as usize,
            ijk[2] as usize,
        )];
        self.bones.contains(&label)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::CpuBackend;
    use crate::volume::Image;

    #[test]
    fn determinant_gradient_matches_finite_differences() {
        let d = [
            Vec3::new(0.3, -0.2, 0.1),
            Vec3::new(-0.4, -0.9, 0.25),
            Vec3::new(0.05, 0.3, -0.6),
        ];
        // An oblique, anisotropic grid: rows of d(index)/d(mm).
        let g = [
            Vec3::new(0.8, 0.1, 0.0),
            Vec3::new(-0.1, 0.75, 0.05),
            Vec3::new(0.0, 0.02, 0.4),
        ];
        let (_, gradient) = determinant_and_gradient(d, g);
        let h = 1e-3;
        for a in 0..3 {
            for c in 0..3 {
                let shifted = |s: f32| {
                    let mut e = d;
                    e[a][c] += s;
                    determinant_and_gradient(e, g).0
                };
                let numeric = (shifted(h) - shifted(-h)) / (2.0 * h);
                assert!(
                    (numeric - gradient[a][c]).abs() < 1e-3,
                    "column {a}, component {c}: {numeric} vs {}",
                    gradient[a][c]
                );
            }
        }
    }

    /// A field that folds along x beside a "bone" whose voxels must not move: smoothing alone
    /// is not asked to help (it is the second step alone); the push lifts every voxel above the
    /// threshold and leaves the bone's displacements as they were.
    #[test]
    fn unfolding_lifts_a_fold_pinned_by_a_bone() {
        let n = 16;
        let grid = Grid::new([n, n, n], Affine::identity()).unwrap();
        // u_x falls by 2.4 mm over two voxels around x = 8: du/dx = −1.2 there, det −0.2.
        let data: Vec<[f32; 3]> = (0..grid.len())
            .map(|m| {
                let i = (m % n) as f32;
                [-2.4 * ((i - 7.0) / 2.0).clamp(0.0, 1.0), 0.0, 0.0]
            })
            .collect();
        let mut field = Image::from_data(grid.clone(), data).unwrap();
        // The bone: the slab x ≥ 8 of the source labels, where the field maps x ≥ 10, right
        // beside the fold.
        let labels = Image::from_data(
            grid.clone(),
            (0..grid.len())
                .map(|m| if m % n >= 8 { 2u16 } else { 1 })
                .collect(),
        )
        .unwrap();
        let before = CpuBackend.jacobian(&field).unwrap();
        assert!(
            before.data.iter().any(|&d| d <= 0.0),
            "the test field must fold"
        );
        let rigid = maps_into_bone(&field, &labels, &[2]);
        let pinned: Vec<[f32; 3]> = (0..grid.len())
            .filter(|&m| rigid[m])
            .map(|m| field.data[m])
            .collect();
        assert!(!pinned.is_empty());
        let lookup = BoneLookup::new(&grid, &labels, &[2]);
        let (left, steps) =
            unfold(&CpuBackend, &mut field, &rigid, &|n, u| lookup.at(n, u)).unwrap();
        assert_eq!(left, 0, "{steps} steps");
        let after = CpuBackend.jacobian(&field).unwrap();
        let least = after.data.iter().cloned().fold(f32::INFINITY, f32::min);
        assert!(least > FOLD_THRESHOLD, "least det {least}");
        let still: Vec<[f32; 3]> = (0..grid.len())
            .filter(|&m| rigid[m])
            .map(|m| field.data[m])
            .collect();
        assert_eq!(pinned, still, "bone voxels moved");
    }
}
