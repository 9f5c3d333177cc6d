// dilate.wgsl: one axis of a box dilation of a mask: 1 where any voxel within `margin`
// along the axis is marked (> 0), else 0. Three passes (x, y, z) dilate by the box, 27 reads a voxel for a
// margin of 2 where one pass over the box would take 125. The last pass can clear the held
// voxels (the fold repair's region never includes them).
//
// Bindings (group 0):
//   0 uniform  DilateParams
//   1 storage  mask: array<f32>   1 float per voxel (> 0: marked)
//   2 storage  held: array<f32>   1 float per voxel (> 0: held)
//   3 storage  out: array<f32>    1 float per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::DilateParams.
struct DilateParams {
    dims: vec4<u32>,   // nx, ny, nz, unused
    axis: u32,         // 0 x, 1 y, 2 z
    clear_held: u32,   // 1: clear the held voxels
    margin: u32,       // voxels
    pad0: u32,
}

@group(0) @binding(0) var<uniform> params: DilateParams;
@group(0) @binding(1) var<storage, read> mask: array<f32>;
@group(0) @binding(2) var<storage, read> held: array<f32>;
@group(0) @binding(3) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let axis = params.axis;
    let m = params.margin;
    let c = gid[axis];
    let lo = max(c, m) - m;
    let hi = min(c + m + 1u, d[axis]);
    var p = gid;
    var near = false;
    for (var a = lo; a < hi && !near; a = a + 1u) {
        p[axis] = a;
        near = mask[voxel_index(p.x, p.y, p.z, d)] > 0.0;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let cleared = params.clear_held == 1u && held[v] > 0.0;
    out[v] = select(0.0, 1.0, near && !cleared);
}
