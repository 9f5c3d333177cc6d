// gain_apply.wgsl: the moving image times the gain, the gain interpolated trilinearly from the
// smoothed grid at each voxel (the point clamped to that grid's outer voxel centres).
//
// Bindings (group 0):
//   0 uniform  GainParams (dims: the moving image's grid)
//   1 storage  gain: array<f32>     on the smoothed grid (gain_ratio)
//   2 storage  moving: array<f32>
//   3 storage  gained: array<f32>   (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

@group(0) @binding(0) var<uniform> params: GainParams;
@group(0) @binding(1) var<storage, read> gain: array<f32>;
@group(0) @binding(2) var<storage, read> moving: array<f32>;
@group(0) @binding(3) var<storage, read_write> gained: array<f32>;

fn sampled_value(index: u32) -> f32 {
    return gain[index];
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let p = vec3<f32>(gid);
    let top = vec3<f32>(params.coarse_dims.xyz) - vec3<f32>(1.0);
    let q = clamp(
        vec3<f32>(
            affine_row(params.to_coarse[0], p),
            affine_row(params.to_coarse[1], p),
            affine_row(params.to_coarse[2], p),
        ),
        vec3<f32>(0.0),
        top,
    );
    let v = voxel_index(gid.x, gid.y, gid.z, d.xyz);
    gained[v] = moving[v] * trilinear(q, params.coarse_dims.xyz, 1.0);
}
