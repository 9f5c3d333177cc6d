// rigid_gn.wgsl: the Gauss-Newton normal equations of the per-bone rigid registration
// (paper eq. 2), reduced per column of the source.
//
// For each source voxel x inside the bone's region (mask >= 0.5) whose moved point y = M x lies
// inside the target: the residual r = T(y) - S(x) and its derivative with respect to a small
// rigid motion (ω, v) of y about the centre c: J = ((y - c) × ∇T(y), ∇T(y)) (world mm).
// One invocation owns one (x, z) column and walks it along y, accumulating 29 sums:
// JᵀJ (upper triangle, 21, row-major), Jᵀr (6), Σ r² (1), voxel count (1). The host folds the
// columns in f64 in a fixed order (rigid::fold_normal_equations) and solves the 6×6 system.
//
// Bindings (group 0):
//   0 uniform  RigidParams
//   1 storage  source: array<f32>   the source level
//   2 storage  mask: array<f32>     the bone-region mask (fractional after pyramids)
//   3 storage  target_image: array<f32>   the target level
//   4 storage  partial: array<f32>  29 sums per column (read_write)
// Dispatch: workgroups (ceil(nx/64), nz, 1).

// Keep in sync with abi::RigidParams.
struct RigidParams {
    dims: vec4<u32>,          // source nx, ny, nz, unused
    target_dims: vec4<u32>,   // target nx, ny, nz, unused
    to_target_index: array<vec4<f32>, 3>,   // source index -> target continuous index
    to_centred_world: array<vec4<f32>, 3>,  // source index -> y - c (world mm)
    gradient_to_world: array<vec4<f32>, 3>, // target index gradient -> world gradient
}

@group(0) @binding(0) var<uniform> params: RigidParams;
@group(0) @binding(1) var<storage, read> source: array<f32>;
@group(0) @binding(2) var<storage, read> mask: array<f32>;
@group(0) @binding(3) var<storage, read> target_image: array<f32>;
@group(0) @binding(4) var<storage, read_write> partial: array<f32>;

fn sampled_value(index: u32) -> f32 {
    return target_image[index];
}

const SUMS: u32 = 29u;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nx = params.dims.x;
    let ny = params.dims.y;
    let x = gid.x;
    let z = gid.y;
    if (x >= nx || z >= params.dims.z) {
        return;
    }
    var acc: array<f32, 29>;
    for (var s = 0u; s < SUMS; s = s + 1u) {
        acc[s] = 0.0;
    }
    let tdims = params.target_dims.xyz;
    for (var y = 0u; y < ny; y = y + 1u) {
        let i = voxel_index(x, y, z, params.dims.xyz);
        if (mask[i] < 0.5) {
            continue;
        }
        let p = vec3<f32>(f32(x), f32(y), f32(z));
        let q = vec3<f32>(
            affine_row(params.to_target_index[0], p),
            affine_row(params.to_target_index[1], p),
            affine_row(params.to_target_index[2], p),
        );
        if (!inside_source(q, tdims)) {
            continue;
        }
        let vg = trilinear_with_gradient(q, tdims);
        let r = vg.x - source[i];
        let g = vec3<f32>(
            linear_row(params.gradient_to_world[0], vg.yzw),
            linear_row(params.gradient_to_world[1], vg.yzw),
            linear_row(params.gradient_to_world[2], vg.yzw),
        );
        let d = vec3<f32>(
            affine_row(params.to_centred_world[0], p),
            affine_row(params.to_centred_world[1], p),
            affine_row(params.to_centred_world[2], p),
        );
        let w = cross(d, g);
        let jac = array<f32, 6>(w.x, w.y, w.z, g.x, g.y, g.z);
        var s = 0u;
        for (var a = 0u; a < 6u; a = a + 1u) {
            for (var b = a; b < 6u; b = b + 1u) {
                acc[s] = acc[s] + jac[a] * jac[b];
                s = s + 1u;
            }
        }
        for (var a = 0u; a < 6u; a = a + 1u) {
            acc[21u + a] = acc[21u + a] + jac[a] * r;
        }
        acc[27] = acc[27] + r * r;
        acc[28] = acc[28] + 1.0;
    }
    let base = (z * nx + x) * SUMS;
    for (var s = 0u; s < SUMS; s = s + 1u) {
        partial[base + s] = acc[s];
    }
}
