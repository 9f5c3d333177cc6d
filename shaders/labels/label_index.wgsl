// label_index.wgsl: per voxel of a label map, 1 + the position of its label among the codes
// (labels.wgsl), 0 for any other label. With one code it is that label's indicator (a bone's
// region); with the bones' codes, which bone each voxel belongs to (the skinning's input).
//
// Bindings (group 0):
//   0 uniform  LabelParams
//   1 storage  labels: array<f32>  1 float per voxel (the label code)
//   2 storage  index: array<f32>   1 float per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::LabelParams.
struct LabelParams {
    dims: vec4<u32>,   // nx, ny, nz, unused
    codes: LabelCodes,
}

@group(0) @binding(0) var<uniform> params: LabelParams;
@group(0) @binding(1) var<storage, read> labels: array<f32>;
@group(0) @binding(2) var<storage, read_write> index: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    index[v] = f32(code_index(labels[v]));
}
