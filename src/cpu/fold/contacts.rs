//! CPU twin of shaders/fold/contacts.wgsl: whether a voxel's difference stencil spans two
//! bones (fold_stats.wgsl's header says why those voxels are counted apart).

use super::threshold::is_held;
use crate::cpu::common::voxel_index;

/// The voxel one step from `c` along `axis` in direction `step` (−1 or 1), the voxel itself at
/// the volume's faces.
fn face_neighbour(c: [u32; 3], axis: usize, step: i32, dims: [u32; 3]) -> u32 {
    let mut p = c;
    if step < 0 && p[axis] > 0 {
        p[axis] -= 1;
    }
    if step > 0 && p[axis] + 1 < dims[axis] {
        p[axis] += 1;
    }
    voxel_index(p[0], p[1], p[2], dims)
}

/// How voxel v's stencil meets the bones (`held` values are bone numbers): whether along one
/// axis its two neighbours (the voxel itself on a face) are held in two different bones, and
/// whether all six are held, in two different bones.
pub fn bone_spans(held: &[f32], dims: [u32; 3], v: u32) -> (bool, bool) {
    let c = [
        v % dims[0],
        (v / dims[0]) % dims[1],
        v / (dims[0] * dims[1]),
    ];
    let first = held[face_neighbour(c, 0, -1, dims) as usize];
    let mut all_held = true;
    let mut two_bones = false;
    let mut spans_along_an_axis = false;
    for axis in 0..3 {
        let lo = held[face_neighbour(c, axis, -1, dims) as usize];
        let hi = held[face_neighbour(c, axis, 1, dims) as usize];
        let both_held = is_held(lo) && is_held(hi);
        all_held = all_held && both_held;
        two_bones = two_bones || lo != first || hi != first;
        spans_along_an_axis = spans_along_an_axis || (both_held && lo != hi);
    }
    (spans_along_an_axis, all_held && two_bones)
}

/// Whether voxel v is a bone contact: its stencil spans two bones either way. Its determinant
/// then takes a difference across the jump from one bone's rigid motion to the other's, or is
/// a function of the bones' motions alone; where they slide on each other it measures the
/// slide.
pub fn is_contact(held: &[f32], dims: [u32; 3], v: u32) -> bool {
    let (along_an_axis, enclosed) = bone_spans(held, dims, v);
    along_an_axis || enclosed
}
