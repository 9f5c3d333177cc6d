//! Removing folds from a field: linear or dual-quaternion blending of bone motions folds soft
//! tissue where a bone turns farther than its weights' falloff is wide (above the patella,
//! behind the knee), and the pull-back of a folded blend has no consistent answer there. Two
//! steps, both leaving bones rigid: broad local smoothing (kernels, where the backend
//! computes), then a targeted push on whatever smoothing could not undo (folds pinned by a
//! bone; images::unfold, also where the backend computes, run only when folds are left). The
//! push also serves a registration's total field ([`unfold_registration`]).

use crate::abi::{
    BoneLookupParams, DilateParams, JacobianParams, ThresholdParams, FOLD_STATS_WIDTH,
};
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;
use crate::images::unfold::{unfold, Bones, Held};
use crate::volume::{Field, Grid, Labels};

pub use crate::images::unfold::FOLD_THRESHOLD;

/// Inversion residual, as a share of the finest voxel spacing, below which a voxel mapped into a
/// bone moves with it (a solved pull-back of a bone voxel is exact to float precision).
const RIGID_RESIDUAL: f32 = 0.1;
/// Most smoothing rounds.
const REPAIR_ROUNDS: usize = 30;
/// Voxels around each folded voxel that are smoothed with it.
const REPAIR_MARGIN: usize = 2;
/// Smoothing sweeps per repair round.
const SWEEPS_PER_ROUND: usize = 3;

/// What a fold repair did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct FoldRepair {
    /// Voxels with det ≤ 0.05 before repair (bone voxels aside in an initial field's repair).
    pub folded_before: usize,
    /// Voxels with det ≤ 0.05 after both steps, bone voxels included.
    pub folded_after: usize,
    /// Rounds of local smoothing kept (the round that did not lower the count is not).
    pub rounds: usize,
    /// Steps of the targeted push.
    pub unfold_steps: usize,
}

/// A Jacobian determinant's fold statistics. Bone contacts — voxels whose difference stencil
/// spans two bones (along one axis its two neighbours move with two different bones, or all six
/// move with bones, two different ones), so that a difference takes the jump from one bone's
/// rigid motion to the other's as the bones slide on each other — are counted apart: a
/// determinant across that jump measures the slide, not a fold, and no field with rigid bones
/// can change it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Folds {
    /// The smallest determinant, bone contacts at or below [`FOLD_THRESHOLD`] aside.
    pub min: f32,
    /// Voxels with det ≤ 0, bone contacts aside: where the map folds.
    pub folded: usize,
    /// Voxels with det ≤ [`FOLD_THRESHOLD`], bone contacts aside.
    pub low: usize,
    /// Of those, the voxels not held.
    pub low_free: usize,
    /// Bone contacts with det ≤ 0.
    pub contacts: usize,
}

/// det J of `field` where the backend computes, and its fold statistics with the voxels where
/// `held` > 0 held (its values bone numbers, which place the bone contacts); only the
/// statistics per chunk of voxels come back.
pub fn determinant<B: Backend>(
    backend: &B,
    field: &DeviceImage<B>,
    held: &B::Buffer<f32>,
) -> Result<(B::Buffer<f32>, Folds)> {
    let det = backend.jacobian(&JacobianParams::new(&field.grid), &field.data)?;
    let params = ThresholdParams::new(&field.grid, FOLD_THRESHOLD);
    let stats = backend.download_one(&backend.fold_stats(&params, &det, held)?)?;
    let mut folds = Folds {
        min: f32::INFINITY,
        folded: 0,
        low: 0,
        low_free: 0,
        contacts: 0,
    };
    for chunk in stats.chunks_exact(FOLD_STATS_WIDTH) {
        folds.min = folds.min.min(chunk[0]);
        folds.folded += chunk[1] as usize;
        folds.low += chunk[2] as usize;
        folds.low_free += chunk[3] as usize;
        folds.contacts += chunk[4] as usize;
    }
    Ok((det, folds))
}

/// det J of a field on the host, by the jacobian kernel.
pub fn host_determinant<B: Backend>(backend: &B, field: &Field) -> Result<Vec<f32>> {
    let params = JacobianParams::new(&field.grid);
    let values = backend.upload(
        "displacement field",
        bytemuck::cast_slice(&field.data).to_vec(),
    )?;
    backend.download_one(&backend.jacobian(&params, &values)?)
}

/// The source label map, on the host (its grid) and where the backend computes.
pub struct SourceLabels<'a, B: Backend> {
    /// On the host.
    pub host: &'a Labels,
    /// Where the backend computes, codes as f32.
    pub device: &'a DeviceImage<B>,
}

/// Removes the folds of an initial field. First it smooths the displacement locally — the
/// voxels with det J ≤ 0.05 and two voxels around them, by 27-neighbour averaging — which
/// undoes most folds and keeps the field smooth, round after round while a round lowers their
/// count; then [`unfold`] lifts what is left. Both leave bone voxels untouched so bones stay
/// rigid, and do not push a soft-tissue voxel's source point into a bone (that would grow the
/// bone in the initialised source: at 60° the patella by 10%), short of [`unfold`]'s last
/// resort, one voxel at a fold no push can lift.
/// A bone voxel is one whose source point lies in one of the `bones` of `labels` *and* whose
/// blend was inverted (`residual`, mm, below [`RIGID_RESIDUAL`] of a voxel): where the blend
/// folds, the pull-back can stop inside a bone without solving it, and those voxels are
/// tissue caught in the fold (at 90° on the paper grid, a folded patch mapped into the
/// patella that nothing else could lift).
pub fn repair_folds<B: Backend>(
    backend: &B,
    mut field: DeviceImage<B>,
    residual: &DeviceImage<B>,
    labels: &SourceLabels<B>,
    bones: &[u16],
) -> Result<(DeviceImage<B>, FoldRepair)> {
    let grid = field.grid.clone();
    let lookup = solved_lookup(labels, &grid, bones)?;
    let held = backend.bone_at_source(&lookup, &field.data, &residual.data, &labels.device.data)?;
    let folded = ThresholdParams::new(&grid, FOLD_THRESHOLD);
    let dilation = DilateParams::passes(&grid, REPAIR_MARGIN);
    let (mut det, mut folds) = determinant(backend, &field, &held)?;
    let mut report = FoldRepair {
        folded_before: folds.low_free,
        ..FoldRepair::default()
    };
    while folds.low_free > 0 && report.rounds < REPAIR_ROUNDS {
        // The voxels not held within REPAIR_MARGIN (along each axis) of a fold not held.
        let mut region = backend.mark_at_most(&folded, &det, &held)?;
        for pass in &dilation {
            region = backend.dilate(pass, &region, &held)?;
        }
        let mut smoothed = field.data.clone();
        for _ in 0..SWEEPS_PER_ROUND {
            smoothed = backend.fold_smooth(&lookup, &smoothed, &region, &labels.device.data)?;
        }
        let smoothed = DeviceImage {
            grid: grid.clone(),
            data: smoothed,
        };
        let (smoothed_det, smoothed_folds) = determinant(backend, &smoothed, &held)?;
        // Smoothing lifts most folds in its first rounds and then stalls, or trades a fold for
        // another (half phantom 60°: 285, 78, 65, 65, 57, 60, ... 62 voxels over 30 rounds):
        // the first round that does not lower the count ends it, its field dropped.
        if smoothed_folds.low_free >= folds.low_free {
            break;
        }
        (field, det, folds) = (smoothed, smoothed_det, smoothed_folds);
        report.rounds += 1;
    }
    if folds.low > 0 {
        (field, report.folded_after, report.unfold_steps) =
            unfold_field(backend, (field, &det), (&held, None), labels, bones)?;
    }
    Ok((field, report))
}

/// The bone (its number, 0 for none) whose rigid motion an initial field moves each voxel by:
/// its source point in one of the `bones` of `labels` and the blend inverted there (`residual`,
/// mm, below [`RIGID_RESIDUAL`] of a voxel). The adaptive warp is held off these voxels, so a
/// registration's total field moves them by their bone's motion too.
pub fn rigid_bones<B: Backend>(
    backend: &B,
    initial: &DeviceImage<B>,
    residual: &DeviceImage<B>,
    labels: &SourceLabels<B>,
    bones: &[u16],
) -> Result<B::Buffer<f32>> {
    let lookup = solved_lookup(labels, &initial.grid, bones)?;
    backend.bone_at_source(&lookup, &initial.data, &residual.data, &labels.device.data)
}

/// The bone lookup of `labels` from `grid` that counts a voxel in a bone only where the blend
/// was inverted (residual below [`RIGID_RESIDUAL`] of a voxel).
fn solved_lookup<B: Backend>(
    labels: &SourceLabels<B>,
    grid: &Grid,
    bones: &[u16],
) -> Result<BoneLookupParams> {
    let solved = RIGID_RESIDUAL * grid.finest_spacing() as f32;
    BoneLookupParams::new(&labels.host.grid, grid, bones, solved)
}

/// The bone (its number, 0 for none) in which `labels` hold each voxel's source point
/// through `field`: which voxels of a registration's total field move with a bone.
pub fn bones_at_source<B: Backend>(
    backend: &B,
    field: &DeviceImage<B>,
    labels: &SourceLabels<B>,
    bones: &[u16],
) -> Result<B::Buffer<f32>> {
    let lookup = BoneLookupParams::new(&labels.host.grid, &field.grid, bones, f32::MAX)?;
    let anywhere = backend.zeros("no residual", field.grid.len())?;
    backend.bone_at_source(&lookup, &field.data, &anywhere, &labels.device.data)
}

/// Unfolds a registration's total field, whose Jacobian determinant is `det` with fold
/// statistics `folds` ([`determinant`]'s): [`unfold`] with the voxels `held` in a bone
/// ([`bones_at_source`]) placing the bone contacts, the voxels at their bone's motion (`rigid`,
/// [`rigid_bones`]; None: those held) held, and tissue pushed into a bone only as its last
/// resort. The adaptive warp is smooth and does not fold (its step control sees to that), but
/// composed with an initial field that is sharply compressed behind a bent knee it can carry a
/// few voxels past each other there.
pub fn unfold_registration<B: Backend>(
    backend: &B,
    field: DeviceImage<B>,
    (det, folds): (&B::Buffer<f32>, &Folds),
    (held, rigid): (&B::Buffer<f32>, Option<&B::Buffer<f32>>),
    labels: &SourceLabels<B>,
    bones: &[u16],
) -> Result<(DeviceImage<B>, FoldRepair)> {
    let mut report = FoldRepair {
        folded_before: folds.low,
        folded_after: folds.low,
        ..FoldRepair::default()
    };
    if folds.low as f64 > UNFOLD_MAX_SHARE * field.grid.len() as f64 {
        // Not a fold to repair but a failed registration (an almost empty target once folded
        // 46% of the voxels, and unfolding took 150 s): left as it is for the checks to report.
        return Ok((field, report));
    }
    let (field, left, steps) = unfold_field(backend, (field, det), (held, rigid), labels, bones)?;
    report.folded_after = left;
    report.unfold_steps = steps;
    Ok((field, report))
}

/// [`unfold`] of `field` (its determinant `det`) where the backend computes, the voxels `held`
/// in bones placing the contacts and those at their bone's motion (`rigid`; None: those held)
/// not moved; then the kernel counts the voxels still at or below the threshold. Returns the
/// field, that count and the sweeps taken.
fn unfold_field<B: Backend>(
    backend: &B,
    (field, det): (DeviceImage<B>, &B::Buffer<f32>),
    (held, rigid): (&B::Buffer<f32>, Option<&B::Buffer<f32>>),
    labels: &SourceLabels<B>,
    bones: &[u16],
) -> Result<(DeviceImage<B>, usize, usize)> {
    let lookup = BoneLookupParams::new(&labels.host.grid, &field.grid, bones, f32::MAX)?;
    let held = Held {
        bones: held,
        rigid: rigid.unwrap_or(held),
    };
    let bones = Bones {
        lookup: &lookup,
        labels: &labels.device.data,
    };
    let (field, steps) = unfold(backend, (&field, det), &held, &bones)?;
    let (_, folds) = determinant(backend, &field, held.bones)?;
    Ok((field, folds.low, steps))
}

/// Share of folded voxels beyond which a field is not unfolded.
const UNFOLD_MAX_SHARE: f64 = 0.05;
