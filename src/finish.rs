//! The finish of a registration, after the stages: the adaptive warp scaled until it does not
//! fold, held off the bones and composed with the initial field; the dense refinement's field
//! unfolded where it still folds; and the outputs made from the whole field (the source
//! resampled once, the Jacobian, the inverse), all brought back together.

use crate::abi::{FadeParams, Interpolation, ResampleParams};
use crate::backend::{Backend, DeviceImage};
use crate::error::{Error, Result};
use crate::images::compose::compose;
use crate::images::fold_repair::{
    bones_at_source, determinant, rigid_bones, unfold_registration, FoldRepair, Folds, SourceLabels,
};
use crate::images::inverse::{invert, round_trip, RoundTrip};
use crate::images::regions;
use crate::init::articulated::{InitialImages, PairImages};
use crate::nonrigid::adaptive::Adaptive;
use crate::volume::{Field, Image, Volume};

/// The whole field where the backend computes, the factor its warp was scaled by, and how
/// it was unfolded.
pub struct TotalField<B: Backend> {
    /// The field, where the backend computes.
    pub field: DeviceImage<B>,
    /// The bone numbers of the voxels whose source point lies in a bone (fold statistics' held).
    pub held: B::Buffer<f32>,
    /// The factor the adaptive warp was scaled by.
    pub scale: f64,
    /// How it was unfolded.
    pub unfolding: FoldRepair,
}

/// The total field of the adaptive warp, held off the bones where the initial field moves them
/// (`bone_map`) over `margin_mm` (0: not held off), and the `initial` field, and the factor the
/// warp was scaled by.
///
/// Step control: the added warp itself must not fold; while it does, it is shrunk. Folds of
/// the initial field (skinning at large angles) are carried into the total field and
/// unfolded there ([`unfolded`]), but are not the warp's to undo. (Counting the total field's
/// folds instead threw away 94% of a good warp at 60° over one voxel sampled differently
/// inside the initial field's fold: 1.34 → 1.77 mm.)
pub fn composed<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    initial: &InitialImages<B>,
    adaptive: &Adaptive,
    bone_map: Option<&DeviceImage<B>>,
    margin_mm: f64,
) -> Result<(DeviceImage<B>, f64)> {
    let grid = &pair.target.grid;
    let nothing_held = backend.zeros("nothing held", grid.len())?;
    let mut scale = 1.0;
    let warp = loop {
        let warp = adaptive.warp_field(backend, scale)?;
        let (_, folds) = determinant(backend, &warp, &nothing_held)?;
        if folds.folded == 0 || scale < 0.1 {
            break warp;
        }
        scale *= 0.5;
    };
    let warp = match bone_map.filter(|_| margin_mm > 0.0) {
        Some(map) => held_off_bones(backend, map, margin_mm, &warp)?,
        None => warp,
    };
    Ok((compose(backend, &warp, &initial.field)?, scale))
}

/// The whole `field` unfolded where it folds (after the dense refinement, which cannot fold
/// it but keeps the initial field's folds, where it ran).
pub fn unfolded<B: Backend>(
    backend: &B,
    (field, scale): (DeviceImage<B>, f64),
    labels: &SourceLabels<B>,
    initial: &InitialImages<B>,
    (bones, bone_map): (&[u16], Option<&DeviceImage<B>>),
    margin_mm: f64,
) -> Result<TotalField<B>> {
    let held = bones_at_source(backend, &field, labels, bones)?;
    let (det, folds) = determinant(backend, &field, &held)?;
    // Only a field that folds is unfolded: the others keep their bits.
    let mut whole = TotalField {
        field,
        held,
        scale,
        unfolding: FoldRepair::default(),
    };
    if folds.folded > 0 {
        // Where the warp is held off the bones, the voxels the initial field moves by a bone's
        // motion keep it; tissue carried into a bone's label may move.
        let rigid = bone_map
            .filter(|_| margin_mm > 0.0)
            .map(|_| rigid_bones(backend, &initial.field, &initial.residual, labels, bones))
            .transpose()?;
        let held_rigid = (&whole.held, rigid.as_ref());
        let repaired = unfold_registration(
            backend,
            whole.field,
            (&det, &folds),
            held_rigid,
            labels,
            bones,
        )?;
        (whole.field, whole.unfolding) = repaired;
    }
    Ok(whole)
}

/// The outputs of a registration, on the host.
pub struct Finished {
    /// The whole field, target point → source point (RAS mm).
    pub field: Field,
    /// The source resampled once through it.
    pub warped: Volume,
    /// Its Jacobian determinant.
    pub jacobian: Volume,
    /// Its inverse, on the source's grid.
    pub inverse: Field,
    /// How closely the inverse undoes the field.
    pub round_trip: RoundTrip,
    /// Its folds.
    pub folds: Folds,
}

/// The whole `field`'s Jacobian and folds (`held` as [`TotalField`]'s), the source resampled
/// once through it and its inverse; all come back together.
pub fn outputs<B: Backend>(
    backend: &B,
    pair: &PairImages<B>,
    field: &DeviceImage<B>,
    held: &B::Buffer<f32>,
) -> Result<Finished> {
    let grid = &pair.target.grid;
    let (det, folds) = determinant(backend, field, held)?;
    let resample = ResampleParams::new(&pair.source.grid, grid, 0.0, Interpolation::Linear);
    let warped = backend.resample(&resample, &pair.source.data, &field.data)?;
    let source_grid = &pair.source.grid;
    let (inverse, residual) = invert(backend, field, source_grid)?;
    let round_trip = round_trip(backend, &residual, &pair.source)?;
    let wanted = [&field.data, &warped, &det, &inverse.data];
    let [field, warped, jacobian, inverse] = backend
        .download(&wanted)?
        .try_into()
        .map_err(|_| Error::Gpu("a download returned the wrong number of buffers".into()))?;
    Ok(Finished {
        field: Image::from_data(grid.clone(), bytemuck::cast_vec(field))?,
        warped: Image::from_data(grid.clone(), warped)?,
        jacobian: Image::from_data(grid.clone(), jacobian)?,
        inverse: Image::from_data(source_grid.clone(), bytemuck::cast_vec(inverse))?,
        round_trip,
        folds,
    })
}

/// The adaptive `warp` held off the `bones` bones: zero where the initial field moves a bone
/// (`bone_map`, crate::init::pins::initial_bones), so that
/// the bones of the total field move exactly by their rigid motions, and rising linearly to
/// the whole warp `margin_mm` from the nearest bone, so that the field has no step at a bone's
/// surface. The warp's pins hold it near zero on each bone's surface already, but between
/// them it bends the bone: by 0.3 mm on average at 90° (the knee at 2 mm), as much as the
/// rigid stage's own error.
fn held_off_bones<B: Backend>(
    backend: &B,
    bone_map: &DeviceImage<B>,
    margin_mm: f64,
    warp: &DeviceImage<B>,
) -> Result<DeviceImage<B>> {
    let distance = regions::distance_to_nearest(backend, bone_map)?;
    let params = FadeParams::new(&warp.grid, margin_mm);
    Ok(DeviceImage {
        data: backend.fade_warp(&params, &warp.data, &distance)?,
        grid: warp.grid.clone(),
    })
}
