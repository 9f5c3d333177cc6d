// fade.wgsl: how much of a warp a voxel keeps near the bones: its distance to the nearest
// bone over the margin, clamped to 1 (0 on the bones, which then move exactly by their rigid
// motions). Shared by fade_warp and dense/field_combine; the kernel declares
// `distance: array<f32>` (mm to each bone, one volume per bone, stacked). Mirrored in
// src/cpu/fade.rs (fade_at).

fn fade_at(v: u32, voxels: u32, bones: u32, margin: f32) -> f32 {
    if (bones == 0u) {
        return 1.0;
    }
    var nearest = distance[v];
    for (var b = 1u; b < bones; b = b + 1u) {
        nearest = min(nearest, distance[b * voxels + v]);
    }
    return select(min(nearest / margin, 1.0), 0.0, nearest <= 0.0);
}
