// gauss_axis.wgsl: one axis's pass of a separable Gaussian smoothing of `components` floats
// per voxel (1 for an image, 3 for a displacement or velocity field), each on its own. The
// taps are symmetric, truncated at the radius and renormalised on the host; a tap past a face
// reads the face's voxel (the values continue flat beyond the grid). Three passes, x, y, z,
// make the 3-D Gaussian with 3 (2r + 1) reads per voxel instead of (2r + 1)³.
//
// Bindings (group 0):
//   0 uniform  GaussParams
//   1 storage  input: array<f32>   `components` floats per voxel
//   2 storage  out: array<f32>     the same, smoothed along the axis (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).
// Invariant: the sum runs from offset −radius to +radius in order, as the CPU twin's does.

// Keep in sync with abi::dense::GaussParams.
struct GaussParams {
    nx: u32,
    ny: u32,
    nz: u32,
    components: u32,      // floats per voxel
    axis: u32,            // 0 x, 1 y, 2 z
    radius: u32,          // taps each side of the centre
    pad0: u32,
    pad1: u32,
    taps: array<vec4<f32>, 8>,   // weight of offset ±t at taps[t / 4][t % 4]
}

@group(0) @binding(0) var<uniform> params: GaussParams;
@group(0) @binding(1) var<storage, read> input: array<f32>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;

fn tap(t: u32) -> f32 {
    return params.taps[t / 4u][t % 4u];
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = vec3<u32>(params.nx, params.ny, params.nz);
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let axis = params.axis;
    let n = i32(d[axis]);
    let c = i32(gid[axis]);
    let r = i32(params.radius);
    let m = params.components;
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    for (var k = 0u; k < m; k = k + 1u) {
        var sum = 0.0;
        var p = gid;
        for (var t = -r; t <= r; t = t + 1) {
            p[axis] = u32(clamp(c + t, 0, n - 1));
            sum = sum + tap(u32(abs(t))) * input[m * voxel_index(p.x, p.y, p.z, d) + k];
        }
        out[m * v + k] = sum;
    }
}
