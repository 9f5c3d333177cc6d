// compose.wgsl: the total field u = R + u0 ∘ (id + R): a target point x reaches its source
// point through the warp first, then through the initial field where the warp lands, so the
// source is resampled once. u0 is read trilinearly at x + R(x), clamped to its grid (beyond
// the grid the initial field's edge values continue). u0 may lie on another grid than R (the
// previous pose's, when poses are chained): x + R(x) is found in its indices.
//
// Bindings (group 0):
//   0 uniform  ComposeParams
//   1 storage  warp: array<f32>     R, 3 floats per voxel
//   2 storage  initial: array<f32>  u0, 3 floats per voxel of its whole grid
//   3 storage  out: array<f32>      u, 3 floats per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::ComposeParams.
struct ComposeParams {
    dims: vec4<u32>,           // nx, ny, nz of R and u, unused
    initial_dims: vec4<u32>,   // nx, ny, nz of u0, unused
    index_to_initial: array<vec4<f32>, 3>,
    mm_to_initial: array<vec4<f32>, 3>,
}

@group(0) @binding(0) var<uniform> params: ComposeParams;
@group(0) @binding(1) var<storage, read> warp: array<f32>;
@group(0) @binding(2) var<storage, read> initial: array<f32>;
@group(0) @binding(3) var<storage, read_write> out: array<f32>;

// The component of u0 that sample.wgsl reads.
var<private> component: u32;

fn sampled_value(index: u32) -> f32 {
    return initial[3u * index + component];
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let o = 3u * voxel_index(gid.x, gid.y, gid.z, d.xyz);
    let r = vec3<f32>(warp[o], warp[o + 1u], warp[o + 2u]);
    let x = vec3<f32>(f32(gid.x), f32(gid.y), f32(gid.z));
    let q = vec3<f32>(
        affine_row(params.index_to_initial[0], x),
        affine_row(params.index_to_initial[1], x),
        affine_row(params.index_to_initial[2], x),
    ) + vec3<f32>(
        linear_row(params.mm_to_initial[0], r),
        linear_row(params.mm_to_initial[1], r),
        linear_row(params.mm_to_initial[2], r),
    );
    let e = params.initial_dims.xyz;
    let qc = clamp(q, vec3<f32>(0.0), vec3<f32>(e) - vec3<f32>(1.0));
    for (var c = 0u; c < 3u; c = c + 1u) {
        component = c;
        out[o + c] = r[c] + trilinear_with_gradient(qc, e).x;
    }
}
