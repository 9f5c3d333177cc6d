// fold_mark.wgsl: 1 on the voxels a fold repair round starts from — not held, with det J at or
// below the threshold — else 0. The round smooths these and a margin around them (dilate).
//
// Bindings (group 0):
//   0 uniform  FoldParams (fold.wgsl)
//   1 storage  det: array<f32>    1 float per voxel
//   2 storage  held: array<f32>   1 float per voxel (> 0: held)
//   3 storage  mark: array<f32>   1 float per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

@group(0) @binding(0) var<uniform> params: FoldParams;
@group(0) @binding(1) var<storage, read> det: array<f32>;
@group(0) @binding(2) var<storage, read> held: array<f32>;
@group(0) @binding(3) var<storage, read_write> mark: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    mark[v] = select(0.0, 1.0, det[v] <= params.threshold.x && !is_held(held[v]));
}
