//! Synthetic poses of a labelled scan, with their exact truth: `bend` (the paper's §4
//! experiment: the shank turned about the flexion axis) and `pose` (the knee set to given
//! joint angles and translations in Grood & Suntay's joint coordinate system). Both move each
//! bone rigidly and blend the motions across the soft tissue by volume skeletal deformation
//! with their own skinning weights (d⁻², not the initialisation's d⁻⁵, so registering a pose is
//! not the initialisation undoing its own model).

use crate::abi::Blending;
use crate::backend::{Backend, DeviceImage};
use crate::error::{Error, Result};
use crate::images::fold_repair::SourceLabels;
use crate::init::articulated::bone_name;
use crate::init::skinning;
use crate::init::vsd::initial_field;
use crate::io::transform::{BoneTransform, BoneTransforms};
use crate::joints::anatomy::{knee_frames, Frame, Side};
use crate::joints::chain;
use crate::joints::joint::{flexion_axis, rotation_about, JointAxis, KneeBones};
use crate::joints::kinematics::{distal_frame, grood_suntay, JointPose};
use crate::labels as label;
use crate::volume::{Affine, Field, Labels, Volume};

/// A synthetic pose of a labelled straight volume.
pub struct Posed {
    /// Target point → straight point (the truth for registering the posed image back).
    pub field: Field,
    /// Bone motions, straight → posed.
    pub truth: BoneTransforms,
}

/// Share of the flexion angle the patella turns by when bending: it rides round the trochlea,
/// held to the tibial tuberosity by the patellar tendon, turning less than the shank.
pub const BEND_PATELLA_SHARE: f64 = 0.7;

/// Shepard exponent of the synthetic poses' skinning weights: d⁻², not the initialisation's
/// d⁻⁵, so the initialisation is not scored against its own weights (with the same weights,
/// the real knee bent 10° was registered to 0.07 mm, a figure about circularity rather than
/// accuracy), and the synthetic deformation stays the smooth one the paper's experiment
/// describes.
pub const BEND_SHEPARD_POWER: u32 = 2;

/// The field that moves each of the knee's bones in `labels` by its motion (`motion_of`) and
/// blends them across the soft tissue, on the source's grid, with the motions as the truth.
fn deform<B: Backend>(
    backend: &B,
    source: &Volume,
    labels: &Labels,
    motion_of: impl Fn(u16) -> Affine,
    blending: Blending,
) -> Result<Posed> {
    let bones = chain::present(&chain::knee(), labels);
    let motions: Vec<Affine> = bones.iter().map(|&b| motion_of(b)).collect();
    let device_labels = DeviceImage::upload_labels(backend, labels)?;
    // Each bone reaches as itself: bend's model does not join bones into segments.
    let distances = skinning::distances(backend, &device_labels, &bones, None)?;
    let weights = distances.weights(backend, BEND_SHEPARD_POWER, skinning::MAX_REACH)?;
    let source_labels = SourceLabels {
        host: labels,
        device: &device_labels,
    };
    let initial = initial_field(
        backend,
        &weights,
        &source_labels,
        &motions,
        blending,
        &source.grid,
    )?;
    let truth = BoneTransforms::new(
        bones
            .iter()
            .zip(&motions)
            .map(|(b, m)| BoneTransform::new(*b, &bone_name(*b), m))
            .collect(),
    );
    Ok(Posed {
        field: initial.field.download_field(backend)?,
        truth,
    })
}

/// Bends `source` by `degrees` with volume skeletal deformation: the femur stays, tibia and
/// fibula turn about the flexion axis (from the labels unless given), the patella by 0.7 of it.
/// Returns the pose and the axis used.
pub fn bend<B: Backend>(
    backend: &B,
    source: &Volume,
    labels: &Labels,
    degrees: f64,
    axis: Option<JointAxis>,
    blending: Blending,
) -> Result<(Posed, JointAxis)> {
    check_bend_degrees(degrees)?;
    let axis = match axis {
        Some(a) => a,
        None => flexion_axis(labels, KneeBones::default())?,
    };
    let motion_of = |b: u16| match b {
        label::FEMUR => Affine::identity(),
        label::PATELLA => rotation_about(&axis, degrees * BEND_PATELLA_SHARE),
        _ => rotation_about(&axis, degrees),
    };
    let mut posed = deform(backend, source, labels, motion_of, blending)?;
    posed.truth.extra.insert(
        "flexion_axis".into(),
        serde_json::json!({
            "point": axis.point.as_slice(),
            "direction": axis.direction.as_slice(),
            "degrees": degrees,
            "patella_share": BEND_PATELLA_SHARE,
            "skinning_power": BEND_SHEPARD_POWER,
            "deformation": "volume skeletal deformation (linear blend skinning), inverted per voxel",
        }),
    );
    Ok((posed, axis))
}

/// The largest flexion `pose` and `bend` make, either way (degrees).
pub const MAX_POSED_FLEXION: f64 = 150.0;

/// Refuses a pose change with a value that is not finite or a flexion beyond
/// [`MAX_POSED_FLEXION`], naming the value.
pub fn check_pose_change(change: JointPose) -> Result<()> {
    let names = [
        "flexion",
        "varus",
        "internal rotation",
        "lateral shift",
        "anterior drawer",
        "compression",
    ];
    if let Some((name, value)) = names
        .iter()
        .zip(change.values())
        .find(|(_, v)| !v.is_finite())
    {
        return Err(Error::InvalidInput(format!(
            "pose: {name} is {value}, not a finite number"
        )));
    }
    if change.flexion_deg.abs() > MAX_POSED_FLEXION {
        return Err(Error::InvalidInput(format!(
            "pose: flexion {}° is not within -{MAX_POSED_FLEXION}..{MAX_POSED_FLEXION}°",
            change.flexion_deg
        )));
    }
    Ok(())
}

/// Refuses a bend angle that is not finite or beyond [`MAX_POSED_FLEXION`].
pub fn check_bend_degrees(degrees: f64) -> Result<()> {
    if !degrees.is_finite() || degrees.abs() > MAX_POSED_FLEXION {
        return Err(Error::InvalidInput(format!(
            "bend angle {degrees}° is not within -{MAX_POSED_FLEXION}..{MAX_POSED_FLEXION}°"
        )));
    }
    Ok(())
}

/// The rigid motion carrying frame `from` onto frame `to`.
fn frame_to_frame(from: &Frame, to: &Frame) -> Affine {
    let r = to.axes * from.axes.transpose();
    let mut m = Affine::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    m.fixed_view_mut::<3, 1>(0, 3)
        .copy_from(&(to.origin - r * from.origin));
    m
}

/// Poses `source` (posereg's knee codes) so that its tibiofemoral joint changes by `change`
/// (flexion, varus, internal rotation in degrees; lateral shift, anterior drawer, compression
/// in mm, as kinematics.csv reports them) from the straight pose: the femur stays, tibia and
/// fibula move together, the patella flexes by 0.7 of the flexion about the femur's medio-
/// lateral axis. Frames as crate::joints::anatomy measures them on `labels`.
pub fn pose<B: Backend>(
    backend: &B,
    source: &Volume,
    labels: &Labels,
    change: JointPose,
    side: Option<Side>,
    blending: Blending,
) -> Result<Posed> {
    check_pose_change(change)?;
    let frames = knee_frames(labels, KneeBones::default())?;
    let side = side.or(frames.side_from_fibula).ok_or_else(|| {
        Error::InvalidInput("pose: no fibula labelled to tell the side; give --side".into())
    })?;
    let tibia_at = distal_frame(
        &frames.femur,
        &(grood_suntay(&frames.femur, &frames.tibia, side) + change),
        side,
    );
    let tibia = frame_to_frame(&frames.tibia, &tibia_at);
    let patella = match frames.patella {
        Some(p) => {
            let flexed = JointPose {
                flexion_deg: BEND_PATELLA_SHARE * change.flexion_deg,
                ..JointPose::default()
            };
            let at = grood_suntay(&frames.femur, &p, side) + flexed;
            frame_to_frame(&p, &distal_frame(&frames.femur, &at, side))
        }
        None => Affine::identity(),
    };
    let motion_of = |b: u16| match b {
        label::FEMUR => Affine::identity(),
        label::PATELLA => patella,
        _ => tibia,
    };
    let mut posed = deform(backend, source, labels, motion_of, blending)?;
    posed.truth.extra.insert(
        "pose".into(),
        serde_json::json!({
            "tibiofemoral_change": {
                "flexion_deg": change.flexion_deg,
                "varus_deg": change.about_e2_deg,
                "internal_rotation_deg": change.about_e3_deg,
                "lateral_shift_mm": change.lateral_mm,
                "anterior_drawer_mm": change.anterior_mm,
                "compression_mm": change.proximal_mm,
            },
            "side": side,
            "patella_share": BEND_PATELLA_SHARE,
            "skinning_power": BEND_SHEPARD_POWER,
        }),
    );
    Ok(posed)
}
