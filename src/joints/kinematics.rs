//! Joint kinematics in Grood & Suntay's joint coordinate system (J Biomech Eng 1983): for a
//! proximal bone's frame P and a distal bone's frame D (crate::joints::anatomy: X to the subject's
//! right, Y anterior, Z proximal), the axes e1 = X_P (fixed in the proximal bone), e3 = Z_D
//! (fixed in the distal bone) and the floating axis e2 = e3 × e1 / |e3 × e1|; then
//!
//! - flexion = atan2(−e2·Z_P, e2·Y_P): rotation about e1, positive as the knee bends (the
//!   distal bone's far end goes posterior);
//! - adduction = asin(e1·e3): about e2, positive for varus (the distal end towards the
//!   midline);
//! - internal rotation = atan2(e2·X_D, e2·Y_D): about e3, positive as the distal bone's
//!   front turns towards the midline;
//! - the translation H = O_D − O_P written on the same axes, H = q1 e1 + q2 e2 + q3 e3 (they
//!   are not orthogonal: e1·e3 is the sine of the adduction): lateral shift q1, anterior
//!   drawer q2, proximal q3.
//!
//! The frames' X points to the subject's right for both knees, which is lateral on a right
//! knee and medial on a left one, so a left knee's adduction, internal rotation and lateral
//! shift are negated: every value means the same on both sides. For the patellofemoral joint
//! (P the femur, D the patella) the same three rotations are the patella's flexion, its spin
//! (positive: its superior pole lateral) and its tilt (reported as lateral tilt, positive when
//! its lateral border goes posterior: the negated rotation about e3).

use crate::error::Result;
use crate::joints::anatomy::{knee_frames, Frame, Side};
use crate::joints::chain::Link;
use crate::joints::confidence::Confidence;
use crate::joints::joint::KneeBones;
use crate::volume::{Affine, Labels};
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use std::collections::BTreeMap;

/// The six values of a joint's pose (degrees, mm).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct JointPose {
    /// Rotation about e1 (flexion).
    pub flexion_deg: f64,
    /// Rotation about e2 (tibiofemoral: varus; patellofemoral: lateral spin).
    pub about_e2_deg: f64,
    /// Rotation about e3 (tibiofemoral: internal rotation; patellofemoral: medial tilt).
    pub about_e3_deg: f64,
    /// Translation along e1, lateral positive.
    pub lateral_mm: f64,
    /// Along e2, anterior positive.
    pub anterior_mm: f64,
    /// Along e3, proximal positive.
    pub proximal_mm: f64,
}

/// The joint coordinate system's six values for the proximal frame `p` and distal frame `d`
/// of a `side` knee.
pub fn grood_suntay(p: &Frame, d: &Frame, side: Side) -> JointPose {
    let (e1, e3) = (p.axis(0), d.axis(2));
    let e2 = e3.cross(&e1).normalize();
    // H's coordinates on the (oblique) axes; they are singular only at ±90° of adduction.
    let on_axes = Matrix3::from_columns(&[e1, e2, e3]);
    let h = on_axes
        .try_inverse()
        .map_or(Vector3::zeros(), |inverse| inverse * (d.origin - p.origin));
    let mirror = match side {
        Side::Right => 1.0,
        Side::Left => -1.0,
    };
    JointPose {
        flexion_deg: (-e2.dot(&p.axis(2))).atan2(e2.dot(&p.axis(1))).to_degrees(),
        about_e2_deg: mirror * e1.dot(&e3).clamp(-1.0, 1.0).asin().to_degrees(),
        about_e3_deg: mirror * e2.dot(&d.axis(0)).atan2(e2.dot(&d.axis(1))).to_degrees(),
        lateral_mm: mirror * h.x,
        anterior_mm: h.y,
        proximal_mm: h.z,
    }
}

/// The distal frame whose joint coordinate system against `p` reads `pose` for a `side` knee:
/// [`grood_suntay`]'s inverse. The distal axes are `p`'s turned by the Cardan sequence about
/// X (−flexion), the intermediate Y (adduction) and the final Z (internal rotation), mirrored
/// for a left knee; its origin is `p`'s moved along e1, e2, e3.
pub fn distal_frame(p: &Frame, pose: &JointPose, side: Side) -> Frame {
    let mirror = match side {
        Side::Right => 1.0,
        Side::Left => -1.0,
    };
    let turn = |axis: Vector3<f64>, degrees: f64| {
        *Rotation3::from_axis_angle(&Unit::new_normalize(axis), degrees.to_radians()).matrix()
    };
    let first = turn(Vector3::x(), -pose.flexion_deg);
    let axes = p.axes
        * first
        * turn(Vector3::y(), mirror * pose.about_e2_deg)
        * turn(Vector3::z(), mirror * pose.about_e3_deg);
    let (e1, e2, e3) = (
        p.axis(0),
        p.axes * first * Vector3::y(),
        axes * Vector3::z(),
    );
    Frame {
        origin: p.origin
            + e1 * (mirror * pose.lateral_mm)
            + e2 * pose.anterior_mm
            + e3 * pose.proximal_mm,
        axes,
    }
}

/// One reported quantity of a joint: its value in the source pose, the target pose, and the
/// change between them.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Quantity {
    /// What it is (see the module's conventions).
    pub name: &'static str,
    /// "deg" or "mm".
    pub unit: &'static str,
    /// In the source pose.
    pub source: f64,
    /// In the target pose.
    pub target: f64,
    /// Target minus source.
    pub change: f64,
}

/// One joint's motion between the scans.
#[derive(Clone, Debug, serde::Serialize)]
pub struct JointMotion {
    /// "tibiofemoral" or "patellofemoral".
    pub joint: &'static str,
    /// Proximal and distal bone.
    pub bones: [String; 2],
    /// The six quantities.
    pub quantities: Vec<Quantity>,
    /// How far each of its bones' registrations can be trusted (empty for given motions).
    pub confidence: BTreeMap<String, Confidence>,
}

/// The names, units and signs of a joint's six quantities, in [`JointPose`]'s order.
const TIBIOFEMORAL: [(&str, &str, f64); 6] = [
    ("flexion", "deg", 1.0),
    ("varus", "deg", 1.0),
    ("internal_rotation", "deg", 1.0),
    ("lateral_shift", "mm", 1.0),
    ("anterior_drawer", "mm", 1.0),
    ("compression", "mm", 1.0),
];
const PATELLOFEMORAL: [(&str, &str, f64); 6] = [
    ("flexion", "deg", 1.0),
    ("lateral_spin", "deg", 1.0),
    ("lateral_tilt", "deg", -1.0),
    ("lateral_shift", "mm", 1.0),
    ("anterior", "mm", 1.0),
    ("proximal", "mm", 1.0),
];

impl std::ops::Add for JointPose {
    type Output = JointPose;
    fn add(self, b: JointPose) -> JointPose {
        let (x, y) = (self.values(), b.values());
        JointPose::from_values(std::array::from_fn(|k| x[k] + y[k]))
    }
}

impl JointPose {
    fn from_values(v: [f64; 6]) -> Self {
        JointPose {
            flexion_deg: v[0],
            about_e2_deg: v[1],
            about_e3_deg: v[2],
            lateral_mm: v[3],
            anterior_mm: v[4],
            proximal_mm: v[5],
        }
    }

    /// The six values in order: flexion, about e2, about e3, lateral, anterior, proximal.
    pub fn values(&self) -> [f64; 6] {
        [
            self.flexion_deg,
            self.about_e2_deg,
            self.about_e3_deg,
            self.lateral_mm,
            self.anterior_mm,
            self.proximal_mm,
        ]
    }
}

impl JointMotion {
    /// The motion of the joint `joint` between poses `source` and `target`.
    pub fn new(
        joint: &'static str,
        bones: [String; 2],
        source: JointPose,
        target: JointPose,
    ) -> Self {
        let names = match joint {
            "patellofemoral" => PATELLOFEMORAL,
            _ => TIBIOFEMORAL,
        };
        let quantities = names
            .iter()
            .zip(source.values().iter().zip(target.values()))
            .map(|(&(name, unit, sign), (&s, t))| Quantity {
                name,
                unit,
                source: sign * s,
                target: sign * t,
                change: sign * (t - s),
            })
            .collect();
        JointMotion {
            joint,
            bones,
            quantities,
            confidence: BTreeMap::new(),
        }
    }

    /// The quantity called `name`.
    pub fn quantity(&self, name: &str) -> Option<&Quantity> {
        self.quantities.iter().find(|q| q.name == name)
    }
}

/// A bone's anatomical frame in both poses (world RAS mm).
#[derive(Clone, Debug, serde::Serialize)]
pub struct BoneFrame {
    /// The bone.
    pub bone: &'static str,
    /// In the source pose, measured on its labels.
    pub source: Frame,
    /// Carried into the target pose by the bone's motion.
    pub target: Frame,
}

/// What kinematics.json holds: the side and how it was known, the frames, and each joint's
/// motion.
#[derive(Clone, Debug, serde::Serialize)]
pub struct KneeKinematics {
    /// Left or right knee.
    pub side: Side,
    /// How the side was known.
    pub side_from: &'static str,
    /// Femur, tibia, and the patella when registered.
    pub frames: Vec<BoneFrame>,
    /// Tibiofemoral, then patellofemoral when the patella was registered.
    pub joints: Vec<JointMotion>,
}

impl KneeKinematics {
    /// Each joint with the confidence `of` its bones (by name), where known.
    pub fn with_confidence(mut self, of: impl Fn(&str) -> Option<Confidence>) -> Self {
        for joint in &mut self.joints {
            for bone in &joint.bones {
                if let Some(c) = of(bone) {
                    joint.confidence.insert(bone.clone(), c);
                }
            }
        }
        self
    }
}

/// The knee's kinematics between the source pose and the target pose the bone `motions`
/// (source → target) reach, with frames from the source's `labels` and the codes of the
/// `chain`'s bones named femur, tibia, patella and fibula. None, with the reason, when they
/// cannot be told: the femur or tibia not registered, or the side neither labelled (no
/// fibula) nor `given`. A warning when the side given contradicts the fibula.
pub fn knee_kinematics(
    labels: &Labels,
    chain: &[Link],
    motions: &[(u16, Affine)],
    given: Option<Side>,
) -> Result<(Option<KneeKinematics>, Vec<String>)> {
    let codes = KneeBones::of_chain(chain)?;
    let motion = |code: u16| motions.iter().find(|m| m.0 == code).map(|m| m.1);
    let (Some(femur_motion), Some(tibia_motion)) = (motion(codes.femur), motion(codes.tibia))
    else {
        let why = "no kinematics: the femur and the tibia must both be registered".to_string();
        return Ok((None, vec![why]));
    };
    let frames = knee_frames(labels, codes)?;
    let mut warnings = Vec::new();
    let (side, side_from) = match (given, frames.side_from_fibula) {
        (Some(side), Some(seen)) if side != seen => {
            warnings.push(format!(
                "--side {side:?} contradicts the labels (the fibula lies on the {seen:?} knee's \
                 lateral side): check the image's orientation; the given side is used"
            ));
            (side, "given (--side)")
        }
        (Some(side), _) => (side, "given (--side)"),
        (None, Some(seen)) => (seen, "the fibula lies lateral to the tibia"),
        (None, None) => {
            let why = "no kinematics: no fibula is labelled to tell a left knee from a right one; \
                       give --side left or --side right";
            return Ok((None, vec![why.to_string()]));
        }
    };
    let frame = |bone, source: Frame, m: &Affine| BoneFrame {
        bone,
        source,
        target: source.moved(m),
    };
    let (femur, tibia) = (
        frame("femur", frames.femur, &femur_motion),
        frame("tibia", frames.tibia, &tibia_motion),
    );
    let joint = |name, p: &BoneFrame, d: &BoneFrame| {
        JointMotion::new(
            name,
            [p.bone.into(), d.bone.into()],
            grood_suntay(&p.source, &d.source, side),
            grood_suntay(&p.target, &d.target, side),
        )
    };
    let mut joints = vec![joint("tibiofemoral", &femur, &tibia)];
    let mut all = vec![femur.clone(), tibia];
    if let (Some(patella), Some(m)) = (frames.patella, codes.patella.and_then(motion)) {
        let patella = frame("patella", patella, &m);
        joints.push(joint("patellofemoral", &femur, &patella));
        all.push(patella);
    }
    let kinematics = KneeKinematics {
        side,
        side_from,
        frames: all,
        joints,
    };
    Ok((Some(kinematics), warnings))
}
