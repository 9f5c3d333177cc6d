// coverage.wgsl: 1 where a target voxel's source point x + u(x) lies inside the source's field
// of view (sample.wgsl's inside_source) and the voxel lies in the target mask, else 0: where
// the resampled source holds data from the scan and not background, and the user counts the
// target as evidence.
//
// Bindings (group 0):
//   0 uniform  ResampleParams (geometry.wgsl)
//   1 storage  field: array<f32>    3 floats per target voxel
//   2 storage  mask: array<f32>     1 float per target voxel (> 0: inside)
//   3 storage  covered: array<f32>  1 float per target voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

@group(0) @binding(0) var<uniform> params: ResampleParams;
@group(0) @binding(1) var<storage, read> field: array<f32>;
@group(0) @binding(2) var<storage, read> mask: array<f32>;
@group(0) @binding(3) var<storage, read_write> covered: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.target_dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let u = vec3<f32>(field[3u * v], field[3u * v + 1u], field[3u * v + 2u]);
    let q = source_index(params, vec3<f32>(gid), u);
    covered[v] = select(0.0, 1.0, inside_source(q, params.source_dims.xyz) && mask[v] > 0.0);
}
