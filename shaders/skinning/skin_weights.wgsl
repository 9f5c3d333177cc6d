// skin_weights.wgsl: skinning weights w_j(x) from each bone's distance map: a partition of unity
// that is exactly 1 inside bone j and 0 inside every other bone, and in soft tissue the
// normalised inverse-distance (Shepard) weights w_j ∝ d_j^-p. Shepard weights need no solve,
// are smooth away from the bones, and let the nearest bone dominate; computed as
// (d_min / d_j)^p so nothing underflows.
//
// Bindings (group 0):
//   0 uniform  SkinWeightsParams
//   1 storage  distance: array<f32>  one volume per bone (mm to the bone, 0 inside), the
//                                    distance maps of shaders/regions/edt.wgsl
//   2 storage  weight: array<f32>    bones floats per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::SkinWeightsParams.
struct SkinWeightsParams {
    dims: vec4<u32>,     // nx, ny, nz, unused
    bones: u32,
    power: u32,          // integer p
    pad0: u32,
    pad1: u32,
    reach: array<vec4<f32>, 2>,  // per bone, the factor its distances are scaled by
}

@group(0) @binding(0) var<uniform> params: SkinWeightsParams;
@group(0) @binding(1) var<storage, read> distance: array<f32>;
@group(0) @binding(2) var<storage, read_write> weight: array<f32>;

// Bone j's distance at voxel v, scaled by its reach.
fn scaled_distance(j: u32, v: u32, voxels: u32) -> f32 {
    return distance[j * voxels + v] * params.reach[j / 4u][j % 4u];
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let bones = params.bones;
    let v = voxel_index(gid.x, gid.y, gid.z, d.xyz);
    let voxels = d.x * d.y * d.z;
    let base = v * bones;
    var inside = bones;
    var nearest = scaled_distance(0u, v, voxels);
    for (var j = 0u; j < bones; j = j + 1u) {
        let dj = scaled_distance(j, v, voxels);
        if (dj <= 0.0 && inside == bones) {
            inside = j;
        }
        nearest = min(nearest, dj);
    }
    if (inside < bones) {
        for (var j = 0u; j < bones; j = j + 1u) {
            weight[base + j] = select(0.0, 1.0, j == inside);
        }
        return;
    }
    var total = 0.0;
    for (var j = 0u; j < bones; j = j + 1u) {
        let ratio = nearest / scaled_distance(j, v, voxels);
        var raw = 1.0;
        for (var k = 0u; k < params.power; k = k + 1u) {
            raw = raw * ratio;
        }
        weight[base + j] = raw;
        total = total + raw;
    }
    for (var j = 0u; j < bones; j = j + 1u) {
        weight[base + j] = weight[base + j] / total;
    }
}
