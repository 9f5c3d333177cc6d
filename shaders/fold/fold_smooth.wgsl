// fold_smooth.wgsl: one sweep of the fold repair's local smoothing. Each voxel of the region
// takes the mean displacement of its 27 neighbours (those inside the grid), summed in z, y, x
// order, unless the mean carries its source point into a bone it was not in (that would grow
// the bone in the initialised source). Every other voxel keeps its displacement. A sweep reads
// one field and writes another, so the order voxels are visited in does not matter.
//
// Bindings (group 0):
//   0 uniform  BoneLookupParams (bone_at_source.wgsl; the residual limit is not used)
//   1 storage  field: array<f32>   3 floats per target voxel (u, mm)
//   2 storage  region: array<f32>  1 float per target voxel (1: smooth it)
//   3 storage  labels: array<f32>  the source label map, 1 float per voxel
//   4 storage  out: array<f32>     3 floats per target voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)) over the target grid.

@group(0) @binding(0) var<uniform> params: BoneLookupParams;
@group(0) @binding(1) var<storage, read> field: array<f32>;
@group(0) @binding(2) var<storage, read> region: array<f32>;
@group(0) @binding(3) var<storage, read> labels: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

fn sampled_value(index: u32) -> f32 {
    return labels[index];
}

fn displacement(v: u32) -> vec3<f32> {
    return vec3<f32>(field[3u * v], field[3u * v + 1u], field[3u * v + 2u]);
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.geometry.target_dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let before = displacement(v);
    var after = before;
    if (region[v] > 0.0) {
        let lo = max(gid, vec3<u32>(1u)) - vec3<u32>(1u);
        let hi = min(gid + vec3<u32>(2u), d);
        var sum = vec3<f32>(0.0);
        var count = 0.0;
        for (var k = lo.z; k < hi.z; k = k + 1u) {
            for (var j = lo.y; j < hi.y; j = j + 1u) {
                for (var i = lo.x; i < hi.x; i = i + 1u) {
                    sum = sum + displacement(voxel_index(i, j, k, d));
                    count = count + 1.0;
                }
            }
        }
        let smoothed = sum / count;
        let p = vec3<f32>(gid);
        if (bone_at(p, smoothed) == 0u || bone_at(p, before) != 0u) {
            after = smoothed;
        }
    }
    out[3u * v] = after.x;
    out[3u * v + 1u] = after.y;
    out[3u * v + 2u] = after.z;
}
