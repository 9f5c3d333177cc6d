//! The push that lifts the folds smoothing leaves (fold_repair.rs) and a registration's last
//! folds, where the backend computes: each folded voxel moves its movable neighbours along the
//! gradient of its own Jacobian determinant until it unfolds, bones held at their motions
//! (shaders/fold/fold_push.wgsl has the push). The lists of voxels to push and the decision to
//! stop are made there too (shaders/fold/push_list.wgsl): the host records sweeps and reads a
//! few hundred bytes of state every few of them, not the field or the lists.

use crate::abi::{
    push_state, AdvanceParams, BoneLookupParams, CandidateParams, JacobianParams, PushParams,
    RefreshParams, Spared,
};
use crate::backend::{Backend, DeviceImage};
use crate::error::{Error, Result};
use crate::volume::Grid;

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
/// cancel and stall). `det` is the field's Jacobian determinant (the jacobian kernel's, which
/// its callers have just computed for their fold statistics). Returns the pushed field (a new
/// buffer) and the sweeps taken; the caller counts what is left.
pub fn unfold<B: Backend>(
    backend: &B,
    (field, det): (&DeviceImage<B>, &B::Buffer<f32>),
    held: &Held<B>,
    bones: &Bones<B>,
) -> Result<(DeviceImage<B>, usize)> {
    let grid = &field.grid;
    let mut pushed = backend.duplicate("unfolded field", &field.data)?;
    let first = Spared::EnclosedByBones;
    let mut sweeps = push_pass(backend, (grid, &mut pushed), det, held, bones, first)?;
    let det = backend.jacobian(&JacobianParams::new(grid), &pushed)?;
    let second = Spared::Contacts;
    sweeps += push_pass(backend, (grid, &mut pushed), &det, held, bones, second)?;
    let grid = grid.clone();
    Ok((DeviceImage { grid, data: pushed }, sweeps))
}

/// One pass of [`unfold`] on `pushed`, whose determinant is `det`, sparing the voxels `spared`
/// names: sweeps until no voxel is left to
/// lift, [`UNFOLD_STEPS`] have run, or [`CONTACTS_ALONE`] have left only bone contacts;
/// returns the sweeps. The lists of voxels to lift and the decision to go on stay where the
/// backend computes (shaders/fold/push_list.wgsl): the host records sweeps and looks at the
/// push's state (a few hundred bytes) every [`SWEEPS_PER_LOOK`].
fn push_pass<B: Backend>(
    backend: &B,
    (grid, pushed): (&Grid, &mut B::Buffer<f32>),
    det: &B::Buffer<f32>,
    held: &Held<B>,
    bones: &Bones<B>,
    spared: Spared,
) -> Result<usize> {
    let mut push = PushLists::new(backend, grid.len())?;
    let lifted = CandidateParams::new(grid, FOLD_THRESHOLD, spared);
    backend.fold_candidates(
        &lifted,
        (det, held.bones),
        &mut push.lists[0],
        &mut push.state,
    )?;
    let advance = AdvanceParams::new(UNFOLD_STEPS, CONTACTS_ALONE);
    backend.fold_advance(&advance, &mut push.state, &mut push.args)?;
    let pass = Pass {
        grid,
        held,
        bones,
        spared,
    };
    let mut recorded = 0;
    loop {
        let state = backend.download_one(&push.state)?;
        if state[push_state::STOPPED] == 1 {
            return Ok(state[push_state::SWEEP] as usize);
        }
        if recorded >= UNFOLD_STEPS {
            return Err(Error::Gpu(format!(
                "the device did not end the fold push after {recorded} sweeps"
            )));
        }
        for _ in 0..SWEEPS_PER_LOOK {
            recorded += 1;
            pass.record_sweep(backend, recorded, pushed, &mut push)?;
            backend.fold_advance(&advance, &mut push.state, &mut push.args)?;
        }
    }
}

/// Sweeps recorded between two looks at the push's state: each look waits for the device,
/// and the sweeps recorded after the pass has ended do nothing (their workgroup counts are 0).
const SWEEPS_PER_LOOK: usize = 8;

/// The fold push's lists and state where the backend computes (shaders/fold/push_list.wgsl).
struct PushLists<B: Backend> {
    /// Two lists as long as the grid: a sweep pushes the voxels of one and lists the next
    /// sweep's in the other.
    lists: [B::Buffer<u32>; 2],
    /// The sweep that last looked at each voxel for the next list, 0 never.
    looked: B::Buffer<u32>,
    /// The sweep each voxel was last blocked in (from 1; 0 never): a tissue voxel no fraction
    /// of a push could move without entering a bone. The next sweep leaves it too and lifts
    /// the folds beside it by their other neighbours.
    blocked: B::Buffer<u32>,
    /// abi::push_state.
    state: B::Buffer<u32>,
    /// The workgroup counts of a sweep's dispatches (abi::push_state::ARGS_LEN).
    args: B::Buffer<u32>,
}

impl<B: Backend> PushLists<B> {
    fn new(backend: &B, voxels: usize) -> Result<Self> {
        Ok(PushLists {
            lists: [
                backend.zeros("voxels to lift", voxels)?,
                backend.zeros("voxels to lift next", voxels)?,
            ],
            looked: backend.zeros("voxels looked at", voxels)?,
            blocked: backend.zeros("blocked voxels", voxels)?,
            state: backend.zeros("fold push state", push_state::LEN)?,
            args: backend.zeros("fold push workgroups", push_state::ARGS_LEN)?,
        })
    }
}

/// What a pass of the push works on.
struct Pass<'a, B: Backend> {
    grid: &'a Grid,
    held: &'a Held<'a, B>,
    bones: &'a Bones<'a, B>,
    spared: Spared,
}

impl<B: Backend> Pass<'_, B> {
    /// Records sweep `sweep` (from 1): each colour's pushes of the sweep's list, then the next
    /// sweep's list made around them.
    fn record_sweep(
        &self,
        backend: &B,
        sweep: usize,
        pushed: &mut B::Buffer<f32>,
        push: &mut PushLists<B>,
    ) -> Result<()> {
        let [first, second] = &mut push.lists;
        let (voxels, next) = match sweep % 2 {
            1 => (&*first, second),
            _ => (&*second, first),
        };
        // The colours forward on odd sweeps and backward on even ones (symmetric Gauss–Seidel):
        // in one direction only, the lists shrank slower (1 mm 90° knee: 675 and 851 sweeps
        // against 533 and 398).
        let colours: Vec<u32> = match sweep % 2 {
            1 => (0..push_state::COLOURS as u32).collect(),
            _ => (0..push_state::COLOURS as u32).rev().collect(),
        };
        let limits = (FOLD_THRESHOLD, UNFOLD_TARGET);
        for colour in colours {
            let params = PushParams::new(self.bones.lookup, self.grid, colour, limits);
            let read = (self.held.rigid, self.bones.labels);
            let counts = (&push.state, &push.args);
            backend.fold_push(&params, voxels, read, pushed, &mut push.blocked, counts)?;
        }
        let params = RefreshParams::new(self.grid, FOLD_THRESHOLD, self.spared);
        let read = (&*pushed, self.held.bones);
        let counts = (&mut push.state, &push.args);
        backend.fold_refresh(&params, (voxels, next), read, &mut push.looked, counts)
    }
}
