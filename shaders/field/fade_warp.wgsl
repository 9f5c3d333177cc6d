// fade_warp.wgsl: the adaptive warp R held off the bones. Each voxel's R is scaled by its
// distance to the nearest bone over the margin, clamped to 1: zero on the bones (which then
// move exactly by their rigid motions in the total field), rising linearly to the whole warp a
// margin away, so that the total field has no step at a bone's surface (fade.wgsl).
//
// Bindings (group 0):
//   0 uniform  FadeParams
//   1 storage  warp: array<f32>       R, 3 floats per voxel
//   2 storage  distance: array<f32>   mm to the nearest bone
//   3 storage  out: array<f32>        the faded R, 3 floats per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::FadeParams.
struct FadeParams {
    dims: vec4<u32>,     // nx, ny, nz, unused
    margin: f32,         // mm over which R rises from 0 to its whole
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: FadeParams;
@group(0) @binding(1) var<storage, read> warp: array<f32>;
@group(0) @binding(2) var<storage, read> distance: array<f32>;
@group(0) @binding(3) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let scale = fade_at(v, 1u, params.margin);
    for (var c = 0u; c < 3u; c = c + 1u) {
        out[3u * v + c] = scale * warp[3u * v + c];
    }
}
