//! The knee in its straight (0°) pose, as signed distances in world RAS mm: the knee joint line
//! at z = 0, the leg along z (superior +z), anterior +y, and lateral +x (a right knee).
//!
//! Intensities imitate a T1-weighted knee MRI (scale about 0–1000): fatty marrow and fat bright,
//! cortical bone and tendons dark, muscle intermediate, cartilage a little brighter than muscle,
//! joint fluid dark, intermuscular septa thin and bright (fatty), vessels dark (flow voids).

use super::shapes::{capsule, coverage, ellipse, ellipsoid, ray_xy, smooth_union};
use glam::{Vec2, Vec3};

pub use crate::labels::{self as label, BONES};

const AIR: f32 = 0.0;
const SKIN: f32 = 450.0;
const FAT: f32 = 950.0;
const SEPTUM: f32 = 800.0;
const MARROW: f32 = 860.0;
const CORTEX: f32 = 60.0;
const CARTILAGE: f32 = 560.0;
const FLUID: f32 = 180.0;
const TENDON: f32 = 80.0;
const VESSEL: f32 = 60.0;

/// Cortical shell thickness (mm).
const CORTEX_MM: f32 = 1.8;
/// Articular cartilage thickness (mm).
const CARTILAGE_MM: f32 = 2.0;
/// Skin and subcutaneous-fat thickness (mm, measured inwards from the body surface).
const SKIN_MM: f32 = 1.5;
const SUBCUTANEOUS_MM: f32 = 8.0;

/// Signed distance to the femur.
pub fn femur(p: Vec3) -> f32 {
    let shaft = capsule(
        p,
        Vec3::new(0.0, -2.0, 60.0),
        Vec3::new(0.0, -2.0, 500.0),
        14.0,
    );
    let metaphysis = ellipsoid(p, Vec3::new(0.0, -1.0, 48.0), Vec3::new(32.0, 19.0, 30.0));
    let lateral = ellipsoid(p, Vec3::new(22.0, -8.0, 22.0), Vec3::new(16.0, 21.0, 21.0));
    let medial = ellipsoid(p, Vec3::new(-22.0, -8.0, 22.0), Vec3::new(17.0, 22.0, 21.0));
    let trochlea = ellipsoid(p, Vec3::new(0.0, 8.0, 34.0), Vec3::new(30.0, 16.0, 18.0));
    let condyles = smooth_union(lateral, medial, 6.0);
    let distal = smooth_union(smooth_union(condyles, trochlea, 6.0), metaphysis, 10.0);
    let bone = smooth_union(distal, shaft, 12.0);
    // The intercondylar notch, cut from behind and below between the condyles.
    let notch = ellipsoid(p, Vec3::new(0.0, -20.0, 8.0), Vec3::new(7.0, 16.0, 16.0));
    bone.max(-notch)
}

/// Signed distance to the tibia: a flat-topped plateau flaring into the shaft, with the
/// tuberosity in front.
pub fn tibia(p: Vec3) -> f32 {
    let plateau =
        ellipsoid(p, Vec3::new(0.0, -6.0, -18.0), Vec3::new(40.0, 27.0, 18.0)).max(p.z + 4.0);
    let shaft = capsule(
        p,
        Vec3::new(0.0, -2.0, -30.0),
        Vec3::new(0.0, 0.0, -500.0),
        13.0,
    );
    let tuberosity = ellipsoid(p, Vec3::new(0.0, 14.0, -38.0), Vec3::new(10.0, 8.0, 14.0));
    smooth_union(smooth_union(plateau, shaft, 10.0), tuberosity, 4.0)
}

/// Signed distance to the fibula (lateral, behind the tibia, head below the plateau).
pub fn fibula(p: Vec3) -> f32 {
    let head = ellipsoid(p, Vec3::new(34.0, -18.0, -42.0), Vec3::new(9.0, 9.0, 10.0));
    let shaft = capsule(
        p,
        Vec3::new(34.0, -18.0, -46.0),
        Vec3::new(30.0, -20.0, -500.0),
        7.0,
    );
    smooth_union(head, shaft, 4.0)
}

/// Signed distance to the patella, in front of the trochlea.
pub fn patella(p: Vec3) -> f32 {
    ellipsoid(p, Vec3::new(0.0, 40.0, 30.0), Vec3::new(22.0, 10.0, 20.0))
}

/// Signed distance to the bone with `label`.
pub fn bone(label: u16, p: Vec3) -> f32 {
    match label {
        label::FEMUR => femur(p),
        label::TIBIA => tibia(p),
        label::PATELLA => patella(p),
        label::FIBULA => fibula(p),
        _ => f32::INFINITY,
    }
}

/// Piecewise-linear body outline along z: (z, rx, ry, centre y).
const OUTLINE: [(f32, f32, f32, f32); 8] = [
    (-500.0, 36.0, 36.0, -6.0),
    (-200.0, 40.0, 44.0, -10.0),
    (-90.0, 50.0, 52.0, -20.0),
    (-40.0, 50.0, 54.0, -6.0),
    (0.0, 54.0, 58.0, 2.0),
    (40.0, 56.0, 58.0, 0.0),
    (150.0, 62.0, 60.0, -2.0),
    (500.0, 66.0, 64.0, -2.0),
];

/// Signed distance to the skin surface (elliptical cross-sections varying along z).
pub fn body(p: Vec3) -> f32 {
    let i = OUTLINE
        .iter()
        .rposition(|o| o.0 <= p.z)
        .unwrap_or(0)
        .min(OUTLINE.len() - 2);
    let (a, b) = (OUTLINE[i], OUTLINE[i + 1]);
    let t = ((p.z - a.0) / (b.0 - a.0)).clamp(0.0, 1.0);
    let lerp = |x: f32, y: f32| x + (y - x) * t;
    ellipse(
        Vec2::new(p.x, p.y),
        Vec2::new(0.0, lerp(a.3, b.3)),
        Vec2::new(lerp(a.1, b.1), lerp(a.2, b.2)),
    )
}

/// Muscle signal by compartment and the distance to the nearest intermuscular septum.
fn muscle(p: Vec3) -> (f32, f32) {
    // Septa radiate from the bone axis; their angles (radians from +x towards +y) differ
    // between the thigh and the calf.
    let (angles, values): (&[f32], &[f32]) = if p.z > 0.0 {
        (&[0.35, 2.45, 4.35, 5.6], &[340.0, 375.0, 320.0, 350.0])
    } else {
        (&[1.05, 2.95, 5.05], &[360.0, 330.0, 300.0])
    };
    let origin = Vec2::new(0.0, -3.0);
    let septum = angles
        .iter()
        .map(|a| ray_xy(p, origin, Vec2::new(a.cos(), a.sin()), 16.0))
        .fold(f32::INFINITY, f32::min);
    let angle = (p.y - origin.y)
        .atan2(p.x - origin.x)
        .rem_euclid(std::f32::consts::TAU);
    let sector = angles.iter().filter(|&&a| a <= angle).count() % values.len();
    (values[sector], septum)
}

/// Label and noise-free, bias-free intensity at a point of the straight pose. Labels have hard
/// boundaries; intensities are anti-aliased over `edge` mm (about one voxel) so the image
/// samples the continuous anatomy without jaggies.
pub fn sample(p: Vec3, edge: f32) -> (f32, u16) {
    let d_body = body(p);
    if d_body > edge {
        return (AIR, label::OUTSIDE);
    }
    let (f, t, pa, fi) = (femur(p), tibia(p), patella(p), fibula(p));
    let code = [
        (f, label::FEMUR),
        (t, label::TIBIA),
        (pa, label::PATELLA),
        (fi, label::FIBULA),
    ]
    .iter()
    .find(|(d, _)| *d <= 0.0)
    .map(|(_, code)| *code)
    .unwrap_or(if d_body <= 0.0 {
        label::SOFT_TISSUE
    } else {
        label::OUTSIDE
    });

    let cover = |d: f32| coverage(d, edge);
    let mut v = AIR;
    let mut paint = |value: f32, amount: f32| v += (value - v) * amount;
    paint(SKIN, cover(d_body));
    paint(FAT, cover(d_body + SKIN_MM));
    let (muscle_value, septum) = muscle(p);
    let deep = cover(d_body + SUBCUTANEOUS_MM);
    paint(muscle_value, deep);
    paint(SEPTUM, deep * cover(septum - 0.8));

    // Around the joint: fat pads, tendons and the popliteal vessels.
    let popliteal_fat = ellipsoid(p, Vec3::new(0.0, -34.0, 5.0), Vec3::new(30.0, 16.0, 48.0));
    let hoffa = ellipsoid(p, Vec3::new(0.0, 25.0, -8.0), Vec3::new(20.0, 9.0, 10.0));
    let patellar_tendon = capsule(
        p,
        Vec3::new(0.0, 44.0, 12.0),
        Vec3::new(0.0, 20.0, -40.0),
        4.5,
    );
    let quadriceps_tendon = capsule(
        p,
        Vec3::new(0.0, 42.0, 46.0),
        Vec3::new(0.0, 30.0, 110.0),
        5.5,
    );
    let vessels = capsule(
        p,
        Vec3::new(-5.0, -38.0, -160.0),
        Vec3::new(-5.0, -38.0, 160.0),
        4.0,
    );
    paint(FAT, cover(popliteal_fat.max(d_body + SKIN_MM)));
    paint(FAT, cover(hoffa));
    paint(TENDON, cover(patellar_tendon.max(d_body + SKIN_MM)));
    paint(TENDON, cover(quadriceps_tendon.max(d_body + SKIN_MM)));
    paint(VESSEL, cover(vessels.max(d_body + SUBCUTANEOUS_MM)));

    // Joint fluid fills the narrow gaps between articulating bones inside the capsule.
    let capsule_d = ellipsoid(p, Vec3::new(0.0, 4.0, 10.0), Vec3::new(46.0, 40.0, 40.0));
    let gap = (f + t - 2.0 * CARTILAGE_MM - 3.0).min(f + pa - 2.0 * CARTILAGE_MM - 5.0);
    paint(FLUID, cover(gap.max(capsule_d)));
    // Articular cartilage: a layer over the joint surfaces only.
    let femoral_cartilage = (f - CARTILAGE_MM).max(p.z - 40.0);
    let tibial_cartilage = (t - CARTILAGE_MM).max(-(p.z + 10.0));
    let patellar_cartilage = (pa - CARTILAGE_MM).max(p.y - 38.0);
    let cartilage = femoral_cartilage
        .min(tibial_cartilage)
        .min(patellar_cartilage);
    paint(CARTILAGE, cover(cartilage));
    let bone_d = f.min(t).min(pa).min(fi);
    paint(CORTEX, cover(bone_d));
    paint(MARROW, cover(bone_d + CORTEX_MM));
    (v, code)
}

/// The rigidly moving groups of bones: the femur, the shank (tibia and fibula), the patella.
pub const GROUPS: [&[u16]; 3] = [
    &[label::FEMUR],
    &[label::TIBIA, label::FIBULA],
    &[label::PATELLA],
];

/// Signed distance to a group of bones.
pub fn group_distance(group: usize, p: Vec3) -> f32 {
    GROUPS[group]
        .iter()
        .map(|&code| bone(code, p))
        .fold(f32::INFINITY, f32::min)
}
