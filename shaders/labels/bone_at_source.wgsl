// bone_at_source.wgsl: per target voxel x, the bone (1 + its position among the codes, 0 for
// none) that the source label map holds at x + u(x), nearest voxel — counted only where the
// voxel's residual is within the limit (an initial field's inversion residual: a voxel whose
// blend was not inverted is tissue caught in a fold, not bone). Which target voxels move with
// a bone: the fold repair holds them, the pins sit on their boundary.
//
// Bindings (group 0):
//   0 uniform  BoneLookupParams
//   1 storage  field: array<f32>     3 floats per target voxel (u, mm)
//   2 storage  residual: array<f32>  1 float per target voxel (mm)
//   3 storage  labels: array<f32>    the source label map, 1 float per voxel
//   4 storage  bone: array<f32>      1 float per target voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)) over the target grid.

@group(0) @binding(0) var<uniform> params: BoneLookupParams;
@group(0) @binding(1) var<storage, read> field: array<f32>;
@group(0) @binding(2) var<storage, read> residual: array<f32>;
@group(0) @binding(3) var<storage, read> labels: array<f32>;
@group(0) @binding(4) var<storage, read_write> bone: array<f32>;

fn sampled_value(index: u32) -> f32 {
    return labels[index];
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.geometry.target_dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let u = vec3<f32>(field[3u * v], field[3u * v + 1u], field[3u * v + 2u]);
    var found = 0u;
    if (residual[v] <= params.limit) {
        found = bone_at(vec3<f32>(gid), u);
    }
    bone[v] = f32(found);
}
