// moments.wgsl: the voxels of a map at or above a threshold — how many, and the sum of their
// world positions — per chunk of consecutive voxels, each chunk in index order and in f64, so
// the results are the same bits on the CPU twin. The host adds the chunks: a region's size
// and centroid without the map leaving the device.
//
// Bindings (group 0):
//   0 uniform  MomentsParams
//   1 storage  values: array<f32>   1 float per voxel
//   2 storage  moments: array<f64>  4 per chunk: count, Σx, Σy, Σz (world mm) (read_write)
// Dispatch: workgroups (ceil(chunks / 64), 1, 1).

// Keep in sync with abi::MomentsParams.
struct MomentsParams {
    dims: vec4<u32>,     // nx, ny, nz, unused
    chunks: vec4<u32>,   // voxels, voxels per chunk, chunks, unused
    threshold: f32,      // value at or above which a voxel counts
    pad0: u32,
    pad1: u32,
    pad2: u32,
    index_to_world: array<vec4<f32>, 3>,
}

@group(0) @binding(0) var<uniform> params: MomentsParams;
@group(0) @binding(1) var<storage, read> values: array<f32>;
@group(0) @binding(2) var<storage, read_write> moments: array<f64>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    let n = params.chunks;
    if (c >= n.z) {
        return;
    }
    let d = params.dims.xyz;
    var count = 0.0lf;
    var sum = vec3<f64>(0.0lf);
    for (var v = c * n.y; v < min((c + 1u) * n.y, n.x); v = v + 1u) {
        if (values[v] >= params.threshold) {
            let p = vec3<f32>(f32(v % d.x), f32((v / d.x) % d.y), f32(v / (d.x * d.y)));
            let w = vec3<f32>(
                affine_row(params.index_to_world[0], p),
                affine_row(params.index_to_world[1], p),
                affine_row(params.index_to_world[2], p),
            );
            count = count + 1.0lf;
            sum = sum + vec3<f64>(w);
        }
    }
    moments[4u * c] = count;
    moments[4u * c + 1u] = sum.x;
    moments[4u * c + 2u] = sum.y;
    moments[4u * c + 3u] = sum.z;
}
