//! kinematics.json and kinematics.csv: the knee's joint motion in Grood & Suntay's joint
//! coordinate system (crate::joints::kinematics), as `init` and `register` write it.

use crate::error::Result;
use crate::joints::kinematics::KneeKinematics;
use std::path::Path;

/// The version of kinematics.json's layout.
pub const KINEMATICS_SCHEMA: u32 = 1;

/// What the values mean, written into kinematics.json.
const CONVENTIONS: &str = "Grood & Suntay joint coordinate system. Frames: X to the subject's \
right, Y anterior, Z proximal (anatomy.rs). e1 = the proximal bone's X, e3 = the distal bone's \
Z, e2 = e3 x e1. Tibiofemoral: flexion (knee bending +), varus (+; valgus -), internal rotation \
of the tibia (+), lateral shift, anterior drawer and compression (+: tibia proximal) of the \
tibia's origin relative to the femur's, along e1, e2, e3. Patellofemoral: flexion, lateral spin \
(superior pole lateral +), lateral tilt (lateral border posterior +), lateral shift, anterior, \
proximal. Left knees are mirrored so every sign means the same on both sides. source: the \
source's pose; target: the pose the bone motions reach; change: target - source.";

/// Writes `folder/kinematics.json` and `folder/kinematics.csv` (each atomically).
pub fn save_kinematics(folder: &Path, kinematics: &KneeKinematics) -> Result<()> {
    let json = serde_json::json!({
        "schema": KINEMATICS_SCHEMA,
        "conventions": CONVENTIONS,
        "side": kinematics.side,
        "side_from": kinematics.side_from,
        "frames": kinematics.frames,
        "joints": kinematics.joints,
    });
    super::save_json(&folder.join("kinematics.json"), &json)?;
    let mut csv = String::from("joint,quantity,unit,source,target,change\n");
    for joint in &kinematics.joints {
        for q in &joint.quantities {
            csv += &format!(
                "{},{},{},{:.4},{:.4},{:.4}\n",
                joint.joint, q.name, q.unit, q.source, q.target, q.change
            );
        }
    }
    super::write_bytes(&folder.join("kinematics.csv"), csv)
}
