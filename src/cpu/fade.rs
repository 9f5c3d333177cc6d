//! CPU twin of shaders/fade.wgsl, shared by the twins of fade_warp and field_combine.

/// How much of a warp voxel `v` keeps: its distance to the nearest of `bones` bones
/// (`distance`: one volume of `voxels` per bone, mm) over `margin`, clamped to 1; 0 on the
/// bones, 1 without bones (fade_at in shaders/fade.wgsl).
#[inline]
pub fn fade_at(distance: &[f32], v: usize, voxels: usize, bones: usize, margin: f32) -> f32 {
    if bones == 0 {
        return 1.0;
    }
    let nearest = (1..bones).fold(distance[v], |m, b| m.min(distance[b * voxels + v]));
    if nearest <= 0.0 {
        0.0
    } else {
        (nearest / margin).min(1.0)
    }
}
