//! The push that lifts the folds smoothing leaves (fold_repair.rs) and a registration's last
//! folds, where the backend computes: each folded voxel moves its movable neighbours along the
//! gradient of its own Jacobian determinant until it unfolds, bones held at their motions
//! (shaders/fold/fold_push.wgsl has the push). The host decides only which voxels a sweep
//! pushes and when to stop: a list of voxel indices comes back each sweep, not the field.

use crate::abi::{
    BoneLookupParams, CandidateParams, JacobianParams, PushParams, RefreshParams, Spared,
};
use crate::backend::reduce::flagged;
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use crate::volume::Grid;
use std::ops::Range;

/// Jacobian determinant below which a voxel counts as folded (or about to fold) for repair.
pub const FOLD_THRESHOLD: f32 = 0.05;

/// Most sweeps of each pass.
const UNFOLD_STEPS: usize = 1000;

/// The determinant each folded voxel is pushed towards.
const UNFOLD_TARGET: f32 = 0.3;

/// Sweeps the first pass goes on while only bone contacts along an axis are left to lift:
/// tissue beside them often lifts them within a few sweeps; where it cannot, the pass would
/// push them to its end (1 mm 90° knee: the initial field's 1000 sweeps, the last 198 on one
/// such voxel) and the second pass leaves them anyway.
const CONTACTS_ALONE: usize = 50;

/// Which voxels of a field move with a bone, for [`unfold`] (bone numbers, 0 for none), where
/// the backend computes. By their source point (`bones`), which places the bone contacts, and
/// by their displacement being their bone's own motion (`rigid`), which no push changes. An
/// initial field's bone voxels are both; a registration's total field can also carry tissue
/// into a bone's label off the bone's motion (at 120°, 3–6 mm off, where the blend was not
/// inverted), which may move.
pub struct Held<'a, B: Backend> {
    /// The bone each voxel's source point lies in.
    pub bones: &'a B::Buffer<f32>,
    /// The bone whose motion each voxel's displacement is.
    pub rigid: &'a B::Buffer<f32>,
}

/// The source label map a push keeps tissue out of the bones of.
pub struct Bones<'a, B: Backend> {
    /// The bones' lookup from the field's grid.
    pub lookup: &'a BoneLookupParams,
    /// The source label map (codes as f32), where the backend computes.
    pub labels: &'a B::Buffer<f32>,
}

/// Lifts every voxel of `field` with det J ≤ [`FOLD_THRESHOLD`]: each pushes its movable
/// neighbours' displacements along the gradient of its own Jacobian determinant, far enough to
/// lift it (linearised) to [`UNFOLD_TARGET`] — the folding correction NiftyReg applies to spline
/// grids, on a dense field. Smoothing cannot undo a fold pinned by a bone (beside a bone whose
/// voxels stay rigid the average pulls the tissue's source point into the bone); this can.
/// Voxels at their bone's motion (`held.rigid`) never move, and no push carries a voxel's
/// source point into one of the `bones`; where every push of a tissue voxel beside a folded
/// bone voxel would, it takes the bone's motion instead (at a deep bend, the voxel between
/// femur and tibia mapped to the wrong side of the femur's surface — 2 mm 90° knee: the last 3
/// folds of the body).
///
/// Bone contacts (placed by `held.bones`) are left (see fold_repair::Folds), in two passes. The
/// first lifts every fold but the voxels whose six stencil neighbours all lie in bones, whose
/// determinant no push changes. The second leaves also the voxels whose difference along one
/// axis spans two bones: tissue beside them can often lift them (the first pass does), but
/// where it cannot, the pushes on them pin the folds beside them (1 mm 90° knee: five such
/// voxels on the femur–tibia contact held a sixth, on its rim, folded).
///
/// A sweep pushes its voxels colour by colour (i, j, k mod 3): the pushes of one colour read
/// and write disjoint neighbourhoods, so they run at once, and each colour sees the colours
/// before it (Gauss–Seidel between colours: simultaneous pushes on a shared neighbour can
/// cancel and stall). Returns the pushed field (a new buffer) and the sweeps taken; the caller
/// counts what is left.
pub fn unfold<B: Backend>(
    backend: &B,
    field: &DeviceImage<B>,
    held: &Held<B>,
    bones: &Bones<B>,
) -> Result<(DeviceImage<B>, usize)> {
    let mut pushed = backend.duplicate("unfolded field", &field.data)?;
    let mut sweeps = 0;
    for spared in [Spared::EnclosedByBones, Spared::Contacts] {
        sweeps += push_pass(backend, (&field.grid, &mut pushed), held, bones, spared)?;
    }
    let grid = field.grid.clone();
    Ok((DeviceImage { grid, data: pushed }, sweeps))
}

/// One pass of [`unfold`], sparing the voxels `spared` names: sweeps until no voxel is left to
/// lift, [`UNFOLD_STEPS`] have run, or [`CONTACTS_ALONE`] have left only bone contacts;
/// returns the sweeps. After each, the flags of the voxels to lift are refreshed around the
/// pushed ones (nothing else can have changed) and the next list is made from the span of
/// voxel indices they lie in.
fn push_pass<B: Backend>(
    backend: &B,
    (grid, pushed): (&Grid, &mut B::Buffer<f32>),
    held: &Held<B>,
    bones: &Bones<B>,
    spared: Spared,
) -> Result<usize> {
    let det = backend.jacobian(&JacobianParams::new(grid), pushed)?;
    let lifted = CandidateParams::new(grid, FOLD_THRESHOLD, spared);
    let mut flags = backend.fold_candidates(&lifted, &det, held.bones)?;
    let mut voxels = flagged(backend, &flags, 0..grid.len())?.0;
    // The sweep each voxel was last blocked in (from 1; 0 never): a tissue voxel no fraction
    // of a push could move without entering a bone. The next sweep leaves it too and lifts
    // the folds beside it by their other neighbours.
    let mut blocked = backend.zeros("blocked voxels", grid.len())?;
    let (mut sweep, mut contacts_alone) = (0, 0);
    while !voxels.is_empty() && sweep < UNFOLD_STEPS && contacts_alone < CONTACTS_ALONE {
        sweep += 1;
        let (span, all) = (near(grid, &voxels), 0..voxels.len());
        let (order, colours) = by_colour(grid, voxels);
        let order = backend.upload("voxels to lift", order)?;
        // The colours forward on odd sweeps and backward on even ones (symmetric Gauss–Seidel):
        // in one direction only, the lists shrank slower (1 mm 90° knee: 675 and 851 sweeps
        // against 533 and 398).
        let colours: Vec<&Range<usize>> = match sweep % 2 {
            1 => colours.iter().collect(),
            _ => colours.iter().rev().collect(),
        };
        for voxels in colours.into_iter().filter(|c| !c.is_empty()) {
            let limits = (FOLD_THRESHOLD, UNFOLD_TARGET);
            let params = PushParams::new(bones.lookup, grid, voxels.clone(), sweep as u32, limits);
            let read = (held.rigid, bones.labels);
            backend.fold_push(&params, &order, read, pushed, &mut blocked)?;
        }
        let params = RefreshParams::new(grid, all, FOLD_THRESHOLD, spared);
        backend.fold_refresh(&params, &order, (pushed, held.bones), &mut flags)?;
        let codes;
        (voxels, codes) = flagged(backend, &flags, span)?;
        // lift_code: 2 marks a bone contact along an axis.
        contacts_alone = match codes.iter().all(|&c| c == 2.0) {
            true => contacts_alone + 1,
            false => 0,
        };
    }
    Ok(sweep)
}

/// The span of voxel indices within two steps of `voxels` (in index order): where a sweep
/// over them can change which voxels are to lift.
fn near(grid: &Grid, voxels: &[u32]) -> Range<usize> {
    let reach = 2 * grid.dims[0] * grid.dims[1];
    let (first, last) = (voxels[0] as usize, voxels[voxels.len() - 1] as usize);
    first.saturating_sub(reach)..(last + reach + 1).min(grid.len())
}

/// `voxels` (in index order) sorted by colour, i mod 3 + 3 (j mod 3) + 9 (k mod 3), each
/// colour's in index order, and where each colour's lie in that order. Two voxels of one colour
/// lie at least three steps apart, so the neighbourhoods one push reads and writes (the voxel
/// and its six stencil neighbours, and theirs for the determinant) never overlap another's
/// writes.
fn by_colour(grid: &Grid, voxels: Vec<u32>) -> (Vec<u32>, [Range<usize>; 27]) {
    let [nx, ny, _] = grid.dims.map(|d| d as u32);
    let colour = |v: u32| (v % nx % 3 + 3 * (v / nx % ny % 3) + 9 * (v / (nx * ny) % 3)) as usize;
    let mut order = voxels;
    order.sort_by_key(|&v| colour(v));
    let mut ranges: [Range<usize>; 27] = Default::default();
    let mut start = 0;
    for (c, range) in ranges.iter_mut().enumerate() {
        let end = start
            + order[start..]
                .iter()
                .take_while(|&&v| colour(v) == c)
                .count();
        *range = start..end;
        start = end;
    }
    (order, ranges)
}
