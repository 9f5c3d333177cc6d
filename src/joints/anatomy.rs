//! Anatomical frames of the knee's bones, measured on the source's bone labels, for the joint
//! coordinate system (kinematics.rs). Every frame is right-handed with X to the subject's
//! right (world +x, RAS), Y anterior and Z proximal; left knees are mirrored when angles are
//! read, not here.
//!
//! - Femur: Z along the shaft (the bone's principal direction nearest the line from the
//!   tibia's centroid to the femur's, away from the tibia); origin
//!   at the centre of the condyles (the distal 25 mm); X the condyles' medio-lateral principal
//!   direction, perpendicular to Z.
//! - Tibia: Z along the shaft (its principal direction nearest that line, towards the femur);
//!   origin at the centre of the plateau (the
//!   proximal 20 mm); X the plateau's medio-lateral principal direction, perpendicular to Z.
//! - Patella: Z and X its principal directions nearest the femur's Z and X (proximal and to
//!   the right), X made perpendicular to Z; origin at its centroid.
//!
//! Knee-only fields of view see neither hip nor ankle, so the shafts' axes are the visible
//! parts' principal directions — the ones along the leg, which in a short field of view need
//! not be the largest. The side (left or right knee) is read from the fibula, which
//! lies lateral to the tibia, or given.

use crate::error::{Error, Result};
use crate::joints::cloud::{
    centroid, end_slab, principal_direction, principal_directions, world_points,
};
use crate::joints::joint::KneeBones;
use crate::volume::{Affine, Labels};
use nalgebra::{Matrix3, Vector3};

/// Depth of the femoral condyles' slab (mm), as the flexion axis uses.
const CONDYLES_MM: f64 = 25.0;
/// Depth of the tibial plateau's slab (mm).
const PLATEAU_MM: f64 = 20.0;
/// A shaft's cross-sections start this far from the bone's joint end (mm): beyond the
/// condyles' and the plateau's flare.
const SHAFT_FROM_JOINT_MM: f64 = 35.0;
/// Thickness of a shaft's cross-section (mm).
const SECTION_MM: f64 = 5.0;
/// Fewest voxels a cross-section needs to count.
const MIN_SECTION_VOXELS: usize = 10;
/// Fewest voxels a bone needs for a frame.
const MIN_VOXELS: usize = 50;

/// An anatomical frame in world RAS mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Origin.
    pub origin: Vector3<f64>,
    /// Unit axes as columns: X (subject's right), Y (anterior), Z (proximal).
    pub axes: Matrix3<f64>,
}

impl Frame {
    /// From an origin, a proximal axis and a roughly medio-lateral one (made perpendicular to
    /// it and pointed to the subject's right).
    fn new(origin: Vector3<f64>, proximal: Vector3<f64>, medio_lateral: Vector3<f64>) -> Self {
        let z = proximal.normalize();
        let mut x = (medio_lateral - z * z.dot(&medio_lateral)).normalize();
        if x.x < 0.0 {
            x = -x;
        }
        let y = z.cross(&x);
        Frame {
            origin,
            axes: Matrix3::from_columns(&[x, y, z]),
        }
    }

    /// Axis `k` (0 X, 1 Y, 2 Z).
    pub fn axis(&self, k: usize) -> Vector3<f64> {
        self.axes.column(k).into_owned()
    }

    /// The frame carried by the rigid motion `m` (world → world).
    pub fn moved(&self, m: &Affine) -> Frame {
        let r = m.fixed_view::<3, 3>(0, 0).into_owned();
        Frame {
            origin: r * self.origin + m.fixed_view::<3, 1>(0, 3),
            axes: r * self.axes,
        }
    }
}

impl serde::Serialize for Frame {
    /// As `{"origin": [x, y, z], "x": [...], "y": [...], "z": [...]}`.
    fn serialize<S: serde::Serializer>(
        &self,
        serializer: S,
    ) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let triple = |v: Vector3<f64>| [v.x, v.y, v.z];
        let mut map = serializer.serialize_map(Some(4))?;
        map.serialize_entry("origin", &triple(self.origin))?;
        for (k, name) in ["x", "y", "z"].iter().enumerate() {
            map.serialize_entry(name, &triple(self.axis(k)))?;
        }
        map.end()
    }
}

/// Which knee.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Side {
    /// A left knee.
    Left,
    /// A right knee.
    Right,
}

/// The knee's frames in the source pose.
#[derive(Clone, Debug, serde::Serialize)]
pub struct KneeFrames {
    /// Femur.
    pub femur: Frame,
    /// Tibia.
    pub tibia: Frame,
    /// Patella, when labelled.
    pub patella: Option<Frame>,
    /// The side read from the fibula (None without one).
    pub side_from_fibula: Option<Side>,
}

fn bone_points(labels: &Labels, code: u16, name: &str) -> Result<Vec<Vector3<f64>>> {
    let points = world_points(labels, code);
    if points.len() < MIN_VOXELS {
        return Err(Error::InvalidInput(format!(
            "the {name}'s frame needs at least {MIN_VOXELS} voxels of label {code}; found {}",
            points.len()
        )));
    }
    Ok(points)
}

/// Of `points`' three principal directions, the one nearest `axis` (either way), pointed
/// along it.
fn principal_nearest(points: &[Vector3<f64>], axis: Vector3<f64>) -> Vector3<f64> {
    let directions = principal_directions(points);
    let column = |k: usize| directions.column(k).into_owned();
    let along = |k: usize| column(k).dot(&axis).abs();
    let k = (0..3)
        .max_by(|&a, &b| along(a).total_cmp(&along(b)))
        .unwrap_or(0);
    let d = column(k);
    if d.dot(&axis) < 0.0 {
        -d
    } else {
        d
    }
}

/// The shaft's axis, pointed as `long` (towards the joint): the line through the centroids of
/// the bone's 5 mm cross-sections more than [`SHAFT_FROM_JOINT_MM`] from its joint end, twice
/// over; `long` where fewer than three sections remain. The principal direction alone leans
/// towards the condyles' or the plateau's bulk when little shaft is seen (the shared knee's
/// femur: 17°, a straight knee read as 21° of varus).
fn shaft_axis(points: &[Vector3<f64>], long: Vector3<f64>) -> Vector3<f64> {
    let mut axis = long;
    for _ in 0..2 {
        let depth = |p: &Vector3<f64>| p.dot(&axis);
        let joint = points.iter().map(depth).fold(f64::NEG_INFINITY, f64::max);
        let mut sections: std::collections::BTreeMap<i64, Vec<Vector3<f64>>> = Default::default();
        for p in points {
            let from_joint = joint - depth(p) - SHAFT_FROM_JOINT_MM;
            if from_joint >= 0.0 {
                let k = (from_joint / SECTION_MM) as i64;
                sections.entry(k).or_default().push(*p);
            }
        }
        let centres: Vec<Vector3<f64>> = (sections.values())
            .filter(|s| s.len() >= MIN_SECTION_VOXELS)
            .map(|s| centroid(s))
            .collect();
        if centres.len() < 3 {
            break;
        }
        let d = principal_direction(&centres, None);
        axis = if d.dot(&axis) < 0.0 { -d } else { d };
    }
    axis
}

/// A long bone's end nearest `towards` (the other bone's centroid): the centre of the slab
/// `depth` mm deep there, the bone's long axis pointed towards `towards`, and the slab's
/// principal direction across it. The long axis is the principal direction nearest the line
/// between the two bones' centroids, not the largest: a field of view that cuts the tibia a
/// few cm below the plateau leaves it wider than long (the shared knee's tibia: its largest
/// direction is medio-lateral). The axis is then refined on the shaft ([`shaft_axis`]).
fn bone_end(
    points: &[Vector3<f64>],
    towards: Vector3<f64>,
    depth: f64,
) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    let long = shaft_axis(
        points,
        principal_nearest(points, towards - centroid(points)),
    );
    let end = end_slab(points, long, depth);
    (centroid(&end), long, principal_direction(&end, Some(long)))
}

/// The patella's frame: of its three principal directions, the one nearest the femur's Z
/// is its Z (a patella may be wider than it is tall, so the longest is not always proximal),
/// the one nearest the femur's X its X.
fn patella_frame(points: &[Vector3<f64>], femur: &Frame) -> Frame {
    Frame::new(
        centroid(points),
        principal_nearest(points, femur.axis(2)),
        principal_nearest(points, femur.axis(0)),
    )
}

/// The knee's frames from the source's labels.
pub fn knee_frames(labels: &Labels, codes: KneeBones) -> Result<KneeFrames> {
    let femur = bone_points(labels, codes.femur, "femur")?;
    let tibia = bone_points(labels, codes.tibia, "tibia")?;
    let (femur_c, tibia_c) = (centroid(&femur), centroid(&tibia));
    // The femur's end nearest the tibia is the condyles; its Z points away from them.
    let (condyles, towards_tibia, across) = bone_end(&femur, tibia_c, CONDYLES_MM);
    let femur_frame = Frame::new(condyles, -towards_tibia, across);
    let (plateau, towards_femur, across) = bone_end(&tibia, femur_c, PLATEAU_MM);
    let tibia_frame = Frame::new(plateau, towards_femur, across);
    let patella = codes
        .patella
        .map(|code| world_points(labels, code))
        .filter(|points| points.len() >= MIN_VOXELS)
        .map(|points| patella_frame(&points, &femur_frame));
    let side_from_fibula = codes.fibula.and_then(|code| {
        let fibula = world_points(labels, code);
        (fibula.len() >= MIN_VOXELS).then(|| {
            let lateral = centroid(&fibula) - tibia_frame.origin;
            match lateral.dot(&tibia_frame.axis(0)) > 0.0 {
                true => Side::Right,
                false => Side::Left,
            }
        })
    });
    Ok(KneeFrames {
        femur: femur_frame,
        tibia: tibia_frame,
        patella,
        side_from_fibula,
    })
}
