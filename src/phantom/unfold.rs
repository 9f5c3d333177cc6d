//! The phantom's own fold push, which makes its truth field fold-free: each folded voxel moves
//! its movable neighbours along the gradient of its own Jacobian determinant until it unfolds,
//! bones held at their motions, sequentially on the host in index order. The registration's
//! push (images::unfold, where the backend computes, in colours) grew from it; the truth keeps
//! its own so that it shares no fold repair with what it measures.

use crate::volume::{Field, Grid};
use glam::Vec3;
use std::collections::BTreeSet;

/// Jacobian determinant below which a voxel counts as folded (or about to fold) for repair.
const FOLD_THRESHOLD: f32 = 0.05;

/// Most unfolding steps.
const UNFOLD_STEPS: usize = 1000;

/// The determinant each folded voxel is pushed towards.
const UNFOLD_TARGET: f32 = 0.3;

/// Lifts every voxel of `field` with det J ≤ [`FOLD_THRESHOLD`]: each pushes its movable
/// neighbours' displacements along the gradient of its own Jacobian determinant, far enough to
/// lift it (linearised) to [`UNFOLD_TARGET`] — the folding correction NiftyReg applies to spline
/// grids, on a dense field. Smoothing cannot undo a fold pinned by a bone (beside a bone whose
/// voxels stay rigid the average pulls the tissue's source point into the bone); this can.
/// Voxels at their bone's motion (`held.rigid` > 0, the bone's number) never move, and no push
/// carries a voxel's source point into a bone (`in_bone(n, u)` says whether voxel n displaced
/// by u lands in one); where every push of a tissue voxel beside a folded bone voxel would, it takes the bone's
/// motion instead (`bone_extended`: at a deep bend, the voxel between femur and tibia mapped
/// to the wrong side of the femur's surface — 2 mm 90° knee: the last 3 folds of the body).
/// Bone contacts (placed by `held.bones`) are left (see [`Folds`]), in two passes. The first
/// lifts every fold but the voxels whose six stencil neighbours all lie in bones, whose
/// determinant no push changes.
/// Where folds are left, the second leaves also the voxels whose difference along one axis
/// spans two bones: tissue beside them can often lift them (the first pass does), but where it
/// cannot, the pushes on them pin the folds beside them (1 mm 90° knee: five such voxels on the
/// femur–tibia contact held a sixth, on its rim, folded). `det` is the field's Jacobian
/// determinant (the jacobian kernel's). Returns the sweeps taken; the caller counts what is
/// left with the kernel.
pub fn unfold(
    field: &mut Field,
    mut det: Vec<f32>,
    Held { bones: held, rigid }: Held,
    in_bone: &(dyn Fn(usize, [f32; 3]) -> bool + Sync),
) -> usize {
    let stencil = Stencil::new(&field.grid);
    let folded = |det: f32| det <= FOLD_THRESHOLD;
    let but_enclosed_by_bones = |v: usize, det: f32| folded(det) && !stencil.all_in_bones(held, v);
    let steps = push_folds(
        &stencil,
        field,
        &mut det,
        rigid,
        in_bone,
        &but_enclosed_by_bones,
    );
    let but_contacts = |v: usize, det: f32| folded(det) && !stencil.is_contact(held, v);
    steps + push_folds(&stencil, field, &mut det, rigid, in_bone, &but_contacts)
}

/// Which voxels of a field move with a bone, for [`unfold`] (bone numbers, 0 for none). By
/// their source point (`bones`), which places the bone contacts, and by their displacement being
/// their bone's own motion (`rigid`), which no push changes. An initial field's bone voxels
/// are both; a registration's total field can also carry tissue into a bone's label off the
/// bone's motion (at 120°, 3–6 mm off, where the blend was not inverted), which may move.
#[derive(Clone, Copy)]
pub struct Held<'a> {
    /// The bone each voxel's source point lies in.
    pub bones: &'a [f32],
    /// The bone whose motion each voxel's displacement is.
    pub rigid: &'a [f32],
}

/// [`unfold`]'s sweeps over the voxels `to_lift` (voxel, det) flags, until none is left or
/// [`UNFOLD_STEPS`] sweeps have run; returns the sweeps.
fn push_folds(
    stencil: &Stencil,
    field: &mut Field,
    det: &mut [f32],
    rigid_in: &[f32],
    in_bone: &(dyn Fn(usize, [f32; 3]) -> bool + Sync),
    to_lift: &dyn Fn(usize, f32) -> bool,
) -> usize {
    let rigid = |q: usize| rigid_in[q] > 0.0;
    let largest_step = field.grid.finest_spacing() as f32 / 4.0;
    // Tissue voxels that no fraction of the last step could move without entering a bone: the
    // next step leaves them and lifts the folds beside them by their other neighbours.
    let mut blocked = BTreeSet::new();
    // The determinants are kept up to date locally: moving voxel q changes det J only at q
    // and its six neighbours (whose differences it enters).
    // Folded voxels that map into a bone count too: they stay, their neighbours move.
    let mut bad = ToLift::new((0..det.len()).map(|n| to_lift(n, det[n])).collect());
    let mut steps = 0;
    while bad.count > 0 && steps < UNFOLD_STEPS {
        // One sweep over the folded voxels in index order, each push applied at once so the
        // next voxel sees it (Gauss-Seidel: simultaneous pushes on a shared neighbour can
        // cancel and stall).
        let refused_before = std::mem::take(&mut blocked);
        for n in bad.sweep() {
            let (now, g) = stencil.determinant(field, n);
            if now > FOLD_THRESHOLD {
                continue;
            }
            // ∂det/∂u at each neighbour in the stencil that may move, with the neighbour
            // opposite it across n.
            let movable: Vec<(usize, Vec3, usize)> = (0..3)
                .zip(stencil.around(n))
                .flat_map(|(a, (lo, hi, factor))| {
                    [(hi, g[a] * factor, lo), (lo, -g[a] * factor, hi)]
                })
                .filter(|&(q, _, _)| {
                    q != n && !rigid(q) && !refused_before.contains(&q) && !blocked.contains(&q)
                })
                .collect();
            let norm: f32 = movable.iter().map(|(_, gq, _)| gq.length_squared()).sum();
            if norm <= f32::EPSILON {
                continue;
            }
            let s = (UNFOLD_TARGET - now) / norm;
            for (q, gq, opposite) in movable {
                let shift = (gq * s).clamp_length_max(largest_step);
                let moved = outside_bones(field, q, shift, in_bone)
                    .or_else(|| bone_extended(field, rigid_in, n, opposite));
                match moved {
                    Some(moved) => field.data[q] = moved,
                    None => {
                        blocked.insert(q);
                        continue;
                    }
                }
                for v in stencil.touched_by(q) {
                    det[v] = stencil.determinant(field, v).0;
                    bad.set(v, to_lift(v, det[v]));
                }
            }
        }
        steps += 1;
    }
    steps
}

/// The voxels [`unfold`] lifts: a flag per voxel, and the voxels that may be flagged (those of
/// the last sweep and those flagged since), from which each sweep takes the flagged ones in
/// index order. Each push refreshes seven determinants; a sorted set of the voxels paid a tree
/// update for each (the push at 1 mm, 90°: 6.9 → 6.0 s with these flags and `Stencil::around`).
struct ToLift {
    flag: Vec<bool>,
    maybe: Vec<usize>,
    /// Voxels flagged.
    count: usize,
}

impl ToLift {
    fn new(flag: Vec<bool>) -> Self {
        let maybe: Vec<usize> = (0..flag.len()).filter(|&n| flag[n]).collect();
        ToLift {
            count: maybe.len(),
            flag,
            maybe,
        }
    }

    fn set(&mut self, v: usize, lift: bool) {
        if lift != self.flag[v] {
            self.flag[v] = lift;
            if lift {
                self.count += 1;
                self.maybe.push(v);
            } else {
                self.count -= 1;
            }
        }
    }

    /// The voxels flagged now, in index order; they stay candidates for the next sweep.
    fn sweep(&mut self) -> Vec<usize> {
        let flag = &self.flag;
        self.maybe.sort_unstable();
        self.maybe.dedup();
        self.maybe.retain(|&v| flag[v]);
        self.maybe.clone()
    }
}

/// Voxel q's displacement moved by `shift`, or, beside a bone where the full step would carry
/// its source point into it, by the longest of 1/2, 1/4, 1/8 of it that does not; None when
/// none of them stays out (a voxel already inside a bone may move).
fn outside_bones(
    field: &Field,
    q: usize,
    shift: Vec3,
    in_bone: &(dyn Fn(usize, [f32; 3]) -> bool + Sync),
) -> Option<[f32; 3]> {
    let from = Vec3::from_array(field.data[q]);
    [1.0, 0.5, 0.25, 0.125]
        .into_iter()
        .map(|f| (from + shift * f).to_array())
        .find(|&moved| !in_bone(q, moved) || in_bone(q, field.data[q]))
}

/// The displacement that extends the rigid motion of the bone holding voxel n one voxel past
/// it, to the neighbour across n from `opposite` (2 u(n) − u(opposite), exact for the bone's
/// affine motion), where n and `opposite` are held in the same bone; None otherwise. A tissue
/// voxel beside a folded bone voxel whose every push would enter that bone then moves with the
/// bone instead: at a deep bend the tissue voxel between femur and tibia can be on the wrong
/// side of the femur's surface, and no push that stays out of the bone lifts the fold.
fn bone_extended(field: &Field, held: &[f32], n: usize, opposite: usize) -> Option<[f32; 3]> {
    let bone = held[n];
    if bone <= 0.0 || opposite == n || held[opposite] != bone {
        return None;
    }
    let u = |v: usize| Vec3::from_array(field.data[v]);
    Some((2.0 * u(n) - u(opposite)).to_array())
}

/// The Jacobian kernel's finite-difference stencil on a grid, on the host: which neighbours it
/// differences at a voxel, and det J there with its gradient.
struct Stencil {
    dims: [usize; 3],
    stride: [usize; 3],
    /// Row a: d(index a)/d(world mm).
    index_per_mm: [Vec3; 3],
}

impl Stencil {
    fn new(grid: &Grid) -> Self {
        let [nx, ny, _] = grid.dims;
        let inv = grid.world_to_voxel_affine();
        Stencil {
            dims: grid.dims,
            stride: [1, nx, nx * ny],
            index_per_mm: std::array::from_fn(|a| {
                Vec3::new(inv[(a, 0)] as f32, inv[(a, 1)] as f32, inv[(a, 2)] as f32)
            }),
        }
    }

    /// The neighbours differenced along each axis at voxel n, and the factor on their
    /// difference: central inside, one-sided on the faces. (All three axes from one split of n
    /// into its indices: the push evaluates this for seven voxels per moved voxel.)
    fn around(&self, n: usize) -> [(usize, usize, f32); 3] {
        let [nx, ny, _] = self.dims;
        let index = [n % nx, n / nx % ny, n / (nx * ny)];
        std::array::from_fn(|a| {
            let (c, stride) = (index[a], self.stride[a]);
            let inside = (c > 0, c + 1 < self.dims[a]);
            let lo = if inside.0 { n - stride } else { n };
            let hi = if inside.1 { n + stride } else { n };
            let factor = if inside.0 && inside.1 { 0.5 } else { 1.0 };
            (lo, hi, factor)
        })
    }

    /// det J of `field` at voxel n from its stencil's differences, and ∂det/∂(column a of D).
    fn determinant(&self, field: &Field, n: usize) -> (f32, [Vec3; 3]) {
        let u = |n: usize| Vec3::from_array(field.data[n]);
        let d = self
            .around(n)
            .map(|(lo, hi, factor)| (u(hi) - u(lo)) * factor);
        determinant_and_gradient(d, self.index_per_mm)
    }

    /// Whether voxel n is a bone contact (`held`: bone numbers, 0 for tissue): along one axis
    /// its two stencil neighbours held in two different bones, or all six held, in two
    /// different bones — the host twin of shaders/fold/fold_stats.wgsl's.
    fn is_contact(&self, held: &[f32], n: usize) -> bool {
        let spans_along_an_axis = self
            .around(n)
            .iter()
            .any(|&(lo, hi, _)| held[lo] > 0.0 && held[hi] > 0.0 && held[lo] != held[hi]);
        spans_along_an_axis || self.all_in_bones(held, n)
    }

    /// Whether voxel n's six stencil neighbours are all held, in two different bones.
    fn all_in_bones(&self, held: &[f32], n: usize) -> bool {
        let neighbours = &self.touched_by(n)[1..];
        let first = held[neighbours[0]];
        neighbours.iter().all(|&v| held[v] > 0.0) && neighbours.iter().any(|&v| held[v] != first)
    }

    /// The voxels whose det J a change at q changes: q and its stencil neighbours (on a face,
    /// q again in place of the missing one).
    fn touched_by(&self, q: usize) -> [usize; 7] {
        let [x, y, z] = self.around(q);
        [q, x.0, x.1, y.0, y.1, z.0, z.1]
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::abi::BoneLookupParams;
    use crate::cpu::CpuBackend;
    use crate::images::fold_repair::host_determinant;
    use crate::sample::bone_at;
    use crate::volume::{Affine, Grid, Image};

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

    /// Whether voxel m of an n³ grid (identity affine) displaced by u lands in the bone whose
    /// source voxels have code 2 in `codes`.
    fn in_bone_of(n: usize, codes: &[f32]) -> impl Fn(usize, [f32; 3]) -> bool + Sync + '_ {
        let grid = Grid::new([n, n, n], Affine::identity()).unwrap();
        let lookup = BoneLookupParams::new(&grid, &grid, &[2], f32::MAX).unwrap();
        move |m: usize, u: [f32; 3]| {
            let p = [m % n, (m / n) % n, m / (n * n)].map(|c| c as f32);
            bone_at(&lookup, codes, p, u) > 0
        }
    }

    /// Unfolds `field`, asserting that it folds before; returns the least det J after and the
    /// sweeps taken.
    fn unfolded(
        field: &mut Field,
        held: Held,
        in_bone: &(dyn Fn(usize, [f32; 3]) -> bool + Sync),
    ) -> (f32, usize) {
        let before = host_determinant(&CpuBackend, field).unwrap();
        assert!(before.iter().any(|&d| d <= 0.0), "the test field must fold");
        let steps = unfold(field, before, held, in_bone);
        let after = host_determinant(&CpuBackend, field).unwrap();
        (after.iter().cloned().fold(f32::INFINITY, f32::min), steps)
    }

    /// Unfolds `field` (an n³ grid, identity affine) beside the bone whose source voxels have
    /// code 2 in `codes`, asserting that it folds nowhere after; returns the voxels held in the
    /// bone.
    fn unfold_beside_bone(field: &mut Field, codes: &[f32]) -> Vec<f32> {
        let in_bone = in_bone_of(field.grid.dims[0], codes);
        let held: Vec<f32> = (0..field.grid.len())
            .map(|m| 2.0 * in_bone(m, field.data[m]) as u8 as f32)
            .collect();
        let both = Held {
            bones: &held,
            rigid: &held,
        };
        let (least, steps) = unfolded(field, both, &in_bone);
        assert!(
            least > FOLD_THRESHOLD,
            "least det {least} after {steps} steps"
        );
        held
    }

    /// Tissue mapped inside a bone off the bone's motion: the bone is the slab 4 ≤ x ≤ 7, which
    /// the field leaves where it is; the tissue voxel x = 8 maps to x = 5.5, inside it, folding
    /// the bone voxel x = 7 (det −0.25). Held as bone by its source point alone, nothing may
    /// move and the fold stays; held only where the field is the bone's motion, x = 8 moves
    /// out and the fold lifts.
    #[test]
    fn tissue_inside_a_bone_off_its_motion_may_move() {
        let n = 16;
        let (field, codes) = slab_and_shifted_voxel(n, -2.5);
        let (grid, data) = (field.grid, field.data);
        let in_bone = in_bone_of(n, &codes);
        let by_source: Vec<f32> = (0..grid.len())
            .map(|m| 2.0 * in_bone(m, data[m]) as u8 as f32)
            .collect();
        let at_motion: Vec<f32> = (0..grid.len())
            .map(|m| 2.0 * (in_bone(m, data[m]) && data[m] == [0.0; 3]) as u8 as f32)
            .collect();
        let least_after = |rigid: &[f32]| {
            let mut field = Image::from_data(grid.clone(), data.clone()).unwrap();
            let held = Held {
                bones: &by_source,
                rigid,
            };
            unfolded(&mut field, held, &in_bone).0
        };
        assert!(
            least_after(&by_source) <= 0.0,
            "held by source point, the fold stays"
        );
        let least = least_after(&at_motion);
        assert!(least > FOLD_THRESHOLD, "least det {least}");
    }

    /// An n³ grid (identity affine) whose source labels hold a bone (code 2) in the slab
    /// 4 ≤ x ≤ 7, tissue (1) elsewhere, and a field that leaves every voxel where it is but
    /// those at x = 8, which it shifts by `shift_x` voxels along x.
    fn slab_and_shifted_voxel(n: usize, shift_x: f32) -> (Field, Vec<f32>) {
        let grid = Grid::new([n, n, n], Affine::identity()).unwrap();
        let data: Vec<[f32; 3]> = (0..grid.len())
            .map(|m| [if m % n == 8 { shift_x } else { 0.0 }, 0.0, 0.0])
            .collect();
        let codes = (0..grid.len())
            .map(|m| if (4..=7).contains(&(m % n)) { 2.0 } else { 1.0 })
            .collect();
        (Image::from_data(grid, data).unwrap(), codes)
    }

    #[test]
    fn a_tissue_voxel_behind_a_bone_moves_with_the_bone() {
        let n = 16;
        // The bone, which the field leaves where it is; the tissue voxel x = 8 maps to x = 2,
        // behind the bone: det −2 at x = 7. Every push that lifts it carries x = 8's source
        // point into the bone (alone they leave det −1.27).
        let (mut field, codes) = slab_and_shifted_voxel(n, -6.0);
        unfold_beside_bone(&mut field, &codes);
        let behind = 8 + n * (7 + n * 7);
        assert_eq!(field.data[behind], [0.0; 3], "x = 8 moves as the bone does");
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
        let codes: Vec<f32> = (0..grid.len())
            .map(|m| if m % n >= 8 { 2.0 } else { 1.0 })
            .collect();
        let before = field.data.clone();
        let held = unfold_beside_bone(&mut field, &codes);
        assert!(held.iter().any(|&h| h > 0.0));
        for m in (0..grid.len()).filter(|&m| held[m] > 0.0) {
            assert_eq!(before[m], field.data[m], "bone voxel {m} moved");
        }
    }
}
