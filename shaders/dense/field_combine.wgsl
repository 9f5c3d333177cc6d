// field_combine.wgsl: out = fade · (a_scale · a + b_scale · b) for two fields of 3 floats per
// voxel: the dense stage's velocity update (the smoothed velocity plus the scaled step, held
// at zero on the bones and faded in over the margin, fade.wgsl), and, with no bones, the
// velocity scaled before it is squared.
//
// Bindings (group 0):
//   0 uniform  CombineParams
//   1 storage  a: array<f32>          3 floats per voxel
//   2 storage  b: array<f32>          3 floats per voxel
//   3 storage  distance: array<f32>   mm to the nearest marked voxel (a bone, or a fold);
//                                     with faded = 0 unused (any buffer)
//   4 storage  out: array<f32>        3 floats per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::dense::CombineParams.
struct CombineParams {
    nx: u32,
    ny: u32,
    nz: u32,
    faded: u32,        // 1: faded by the distance to the nearest marked voxel; 0: not
    a_scale: f32,
    b_scale: f32,
    margin_mm: f32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> params: CombineParams;
@group(0) @binding(1) var<storage, read> a: array<f32>;
@group(0) @binding(2) var<storage, read> b: array<f32>;
@group(0) @binding(3) var<storage, read> distance: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = vec3<u32>(params.nx, params.ny, params.nz);
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let fade = fade_at(v, params.faded, params.margin_mm);
    for (var c = 0u; c < 3u; c = c + 1u) {
        out[3u * v + c] = fade * (params.a_scale * a[3u * v + c] + params.b_scale * b[3u * v + c]);
    }
}
