//! Label codes of the bone label maps posereg reads and the phantom writes (ARCHITECTURE.md):
//! the knee's bones and what is not bone.

/// Outside the body.
pub const OUTSIDE: u16 = 0;
/// Soft tissue (skin, fat, muscle, cartilage, tendon, fluid).
pub const SOFT_TISSUE: u16 = 1;
/// Femur.
pub const FEMUR: u16 = 2;
/// Tibia.
pub const TIBIA: u16 = 3;
/// Patella.
pub const PATELLA: u16 = 4;
/// Fibula.
pub const FIBULA: u16 = 5;

/// The bones, in label order.
pub const BONES: [(u16, &str); 4] = [
    (FEMUR, "femur"),
    (TIBIA, "tibia"),
    (PATELLA, "patella"),
    (FIBULA, "fibula"),
];
