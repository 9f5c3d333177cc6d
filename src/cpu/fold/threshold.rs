//! CPU twin of shaders/fold/threshold.wgsl, shared by fold_stats and mark_at_most.

/// Whether a voxel of the held map is held (> 0: it moves with a bone, and the fold repair
/// never changes it).
#[inline]
pub fn is_held(value: f32) -> bool {
    value > 0.0
}
