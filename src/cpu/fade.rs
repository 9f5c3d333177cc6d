//! CPU twin of shaders/fade.wgsl, shared by the twins of fade_warp and field_combine.

/// How much of a warp voxel `v` keeps: its distance to the nearest bone (`distance`, mm) over
/// `margin`, clamped to 1; 0 on the bones, 1 where nothing is `faded` (fade_at in
/// shaders/fade.wgsl).
#[inline(always)]
pub fn fade_at(distance: &[f32], v: usize, faded: u32, margin: f32) -> f32 {
    if faded == 0 {
        return 1.0;
    }
    let nearest = distance[v];
    if nearest <= 0.0 {
        0.0
    } else {
        (nearest / margin).min(1.0)
    }
}
