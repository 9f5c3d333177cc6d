//! The knee's flexion axis, found from the bone labels of the straight (source) scan: through
//! the femoral condyles, medio-lateral, oriented so that a positive rotation swings the shank
//! posteriorly — the direction a knee bends.

use crate::error::{Error, Result};
use crate::joints::chain::{self, Link};
use crate::joints::cloud::{centroid, end_slab, principal_direction, world_points};
use crate::labels as label;
use crate::volume::Labels;
use nalgebra::Vector3;

/// A rotation axis in world RAS mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointAxis {
    /// A point on the axis: the centre of the distal femur (the condyles).
    pub point: Vector3<f64>,
    /// Unit direction; positive rotations flex the knee.
    pub direction: Vector3<f64>,
    /// Unit long axis of the femur, pointing proximally (away from the knee).
    pub long_axis: Vector3<f64>,
    /// Unit anterior direction, perpendicular to the long axis.
    pub anterior: Vector3<f64>,
}

/// Thickness of the distal femur slab that locates the condyles (mm).
const CONDYLE_SLAB_MM: f64 = 25.0;

/// The label codes of the knee's bones, the flexion axis's and the anatomical frames': the
/// chain's bones named femur, tibia, patella and fibula, so that a label map with other codes
/// works unchanged.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KneeBones {
    /// The femur's code.
    pub femur: u16,
    /// The tibia's code.
    pub tibia: u16,
    /// The patella's code, if the chain has one.
    pub patella: Option<u16>,
    /// The fibula's code, if the chain has one.
    pub fibula: Option<u16>,
}

impl KneeBones {
    /// The codes of the chain's bones named femur, tibia, patella and fibula.
    pub fn of_chain(chain: &[Link]) -> Result<Self> {
        let code = |name: &str| chain.iter().find(|l| l.name == name).map(|l| l.label);
        match (code("femur"), code("tibia")) {
            (Some(femur), Some(tibia)) => Ok(KneeBones {
                femur,
                tibia,
                patella: code("patella"),
                fibula: code("fibula"),
            }),
            _ => Err(Error::InvalidInput(format!(
                "the flexion axis is found from the bones named femur and tibia, and the \
                 kinematic chain ({}) lacks one",
                chain::described(chain)
            ))),
        }
    }
}

impl Default for KneeBones {
    /// The codes posereg's phantom and ARCHITECTURE.md use: 2 femur, 3 tibia, 4 patella,
    /// 5 fibula.
    fn default() -> Self {
        KneeBones {
            femur: label::FEMUR,
            tibia: label::TIBIA,
            patella: Some(label::PATELLA),
            fibula: Some(label::FIBULA),
        }
    }
}

/// The flexion axis from femur and tibia labels (patella, when present, fixes anterior;
/// otherwise world anterior +y is used).
pub fn flexion_axis(labels: &Labels, bones: KneeBones) -> Result<JointAxis> {
    let femur = world_points(labels, bones.femur);
    let tibia = world_points(labels, bones.tibia);
    if femur.len() < 50 || tibia.len() < 50 {
        return Err(Error::InvalidInput(format!(
            "finding the flexion axis needs femur (label {}) and tibia (label {}) voxels; found {} and {}",
            bones.femur,
            bones.tibia,
            femur.len(),
            tibia.len()
        )));
    }
    let mut long_axis = principal_direction(&femur, None);
    if long_axis.dot(&(centroid(&femur) - centroid(&tibia))) < 0.0 {
        long_axis = -long_axis;
    }
    let condyles = end_slab(&femur, -long_axis, CONDYLE_SLAB_MM);
    let point = centroid(&condyles);
    let medio_lateral = principal_direction(&condyles, Some(long_axis));
    let patella = bones
        .patella
        .map_or_else(Vec::new, |code| world_points(labels, code));
    let towards_front = if patella.len() >= 20 {
        centroid(&patella) - point
    } else {
        Vector3::new(0.0, 1.0, 0.0)
    };
    let mut anterior = long_axis.cross(&medio_lateral).normalize();
    if anterior.dot(&towards_front) < 0.0 {
        anterior = -anterior;
    }
    // Rotating about long × anterior carries a point below the knee (−long) towards −anterior.
    let direction = long_axis.cross(&anterior).normalize();
    Ok(JointAxis {
        point,
        direction,
        long_axis,
        anterior,
    })
}

/// The rigid motion rotating by `degrees` about `axis` (world → world).
pub fn rotation_about(axis: &JointAxis, degrees: f64) -> crate::volume::Affine {
    let r = nalgebra::Rotation3::from_axis_angle(
        &nalgebra::Unit::new_normalize(axis.direction),
        degrees.to_radians(),
    );
    let t = axis.point - r * axis.point;
    let mut m = crate::volume::Affine::identity();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(r.matrix());
    m.fixed_view_mut::<3, 1>(0, 3).copy_from(&t);
    m
}

/// The angle (degrees) of the rotation part of a rigid motion.
pub fn rotation_degrees(m: &crate::volume::Affine) -> f64 {
    ((m[(0, 0)] + m[(1, 1)] + m[(2, 2)] - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// The rotation angle between two motions (degrees); infinite when `a` is singular.
pub fn degrees_between(a: &crate::volume::Affine, b: &crate::volume::Affine) -> f64 {
    a.try_inverse()
        .map_or(f64::INFINITY, |inv| rotation_degrees(&(inv * b)))
}
