// mark_at_most.wgsl: 1 on the voxels not held whose value is at or below the threshold, else 0:
// the voxels a fold repair round starts from (det J; it smooths them and a margin around them,
// dilate), or a region grown by a distance (a distance map in mm, nothing held).
//
// Bindings (group 0):
//   0 uniform  ThresholdParams (threshold.wgsl)
//   1 storage  value: array<f32>  1 float per voxel
//   2 storage  held: array<f32>   1 float per voxel (> 0: held)
//   3 storage  mark: array<f32>   1 float per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

@group(0) @binding(0) var<uniform> params: ThresholdParams;
@group(0) @binding(1) var<storage, read> value: array<f32>;
@group(0) @binding(2) var<storage, read> held: array<f32>;
@group(0) @binding(3) var<storage, read_write> mark: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    mark[v] = select(0.0, 1.0, value[v] <= params.threshold && !is_held(held[v]));
}
