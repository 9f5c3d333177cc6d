// local_moments.wgsl: one axis's pass of box sums for the local correlation of two images a
// and b on one grid. Per voxel, 5 sums over the voxels within `radius` along the axis (cut
// at the grid's faces): the first pass (x) sums a, b, a², b², ab from the two images; the y
// and z passes sum the stack the pass before wrote. Three passes of 2r + 1 reads make the
// (2r + 1)³ box, which one pass would read per voxel.
//
// Bindings (group 0):
//   0 uniform  LocalMomentsParams
//   1 storage  input: array<f32>  first pass: a, 1 float per voxel; else 5 floats per voxel
//   2 storage  other: array<f32>  first pass: b, 1 float per voxel; else unused
//   3 storage  out: array<f32>    5 floats per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::LocalMomentsParams.
struct LocalMomentsParams {
    dims: vec4<u32>,   // nx, ny, nz, unused
    axis: u32,         // 0 x, 1 y, 2 z
    first: u32,        // 1 on the first pass
    radius: u32,       // the window's radius (voxels)
    pad0: u32,
}

@group(0) @binding(0) var<uniform> params: LocalMomentsParams;
@group(0) @binding(1) var<storage, read> input: array<f32>;
@group(0) @binding(2) var<storage, read> other: array<f32>;
@group(0) @binding(3) var<storage, read_write> out: array<f32>;

// The 5 moments voxel v adds: from the two images on the first pass, else the stack's.
fn moments_at(v: u32) -> array<f32, 5> {
    if (params.first == 1u) {
        let a = input[v];
        let b = other[v];
        return array<f32, 5>(a, b, a * a, b * b, a * b);
    }
    return array<f32, 5>(input[5u * v], input[5u * v + 1u], input[5u * v + 2u],
                         input[5u * v + 3u], input[5u * v + 4u]);
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let axis = params.axis;
    let r = params.radius;
    let c = gid[axis];
    var p = gid;
    var sums = array<f32, 5>(0.0, 0.0, 0.0, 0.0, 0.0);
    for (var a = max(c, r) - r; a < min(c + r + 1u, d[axis]); a = a + 1u) {
        p[axis] = a;
        let m = moments_at(voxel_index(p.x, p.y, p.z, d));
        for (var k = 0u; k < 5u; k = k + 1u) {
            sums[k] = sums[k] + m[k];
        }
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    for (var k = 0u; k < 5u; k = k + 1u) {
        out[5u * v + k] = sums[k];
    }
}
