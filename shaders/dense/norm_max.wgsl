// norm_max.wgsl: the largest length of a vector field's vectors per chunk of NormParams'
// per_chunk vectors, in index order: the host takes the maximum of the few partials (the
// dense stage scales its update so that no voxel moves further than its step).
//
// Bindings (group 0):
//   0 uniform  NormParams
//   1 storage  field: array<f32>     3 floats per vector
//   2 storage  maxima: array<f32>    one per chunk (read_write)
// Dispatch: workgroups (ceil(chunks / 64), 1, 1).

// Keep in sync with abi::dense::NormParams.
struct NormParams {
    vectors: u32,
    per_chunk: u32,
    chunks: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: NormParams;
@group(0) @binding(1) var<storage, read> field: array<f32>;
@group(0) @binding(2) var<storage, read_write> maxima: array<f32>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    if (c >= params.chunks) {
        return;
    }
    var largest = 0.0;
    for (var v = c * params.per_chunk; v < min((c + 1u) * params.per_chunk, params.vectors); v = v + 1u) {
        let u = vec3<f32>(field[3u * v], field[3u * v + 1u], field[3u * v + 2u]);
        largest = max(largest, sqrt(u.x * u.x + u.y * u.y + u.z * u.z));
    }
    maxima[c] = largest;
}
