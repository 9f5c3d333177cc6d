// fade.wgsl: how much of a warp a voxel keeps near the bones: its distance to the nearest
// bone over the margin, clamped to 1 (0 on the bones, which then move exactly by their rigid
// motions); 1 everywhere where nothing is faded. Shared by fade_warp and dense/field_combine;
// the kernel declares `distance: array<f32>` (mm to the nearest bone,
// images::regions::distance_to_nearest). Mirrored in src/cpu/fade.rs (fade_at).

fn fade_at(v: u32, faded: u32, margin: f32) -> f32 {
    if (faded == 0u) {
        return 1.0;
    }
    let nearest = distance[v];
    return select(min(nearest / margin, 1.0), 0.0, nearest <= 0.0);
}
