// lncc_terms.wgsl: the local-correlation cost of the moving image a = W against the target
// b = T, and what its gradient needs, from their box sums (local_moments.wgsl).
//
// The cost is K Σ_w c_w (1 − ρ_w²) over the windows w (one centred on each voxel; c_w the
// coverage at its centre, K `params.scale`); a flat window adds K c_w and no gradient. With
// α = cab / (va vb) and β = α cab / va (window.wgsl), ∂ρ_w²/∂a_v = (2 / n)(α (b_v − mb) −
// β (a_v − ma)) for every voxel v of w, so
//   ∂cost/∂a_v = −2 (b_v A1 − A2 − a_v A3 + A4),
// where A1..A4 are box sums, over the windows holding v, of the per-window terms this kernel
// writes: K c α / n, K c α mb / n, K c β / n, K c β ma / n (and a 0 fifth, so that
// local_moments' stack passes sum them). lncc_gradient.wgsl finishes it.
//
// Bindings (group 0):
//   0 uniform  LnccTermsParams
//   1 storage  sums: array<f32>     5 floats per voxel (local_moments.wgsl, last pass)
//   2 storage  covered: array<f32>  coverage c per voxel (counted where is_covered)
//   3 storage  terms: array<f32>    5 floats per voxel (read_write)
//   4 storage  rows: array<f32>     1 float per row (j, k), K Σ c (1 − ρ²) in x order (read_write)
// Dispatch: workgroups (ceil(ny/8), ceil(nz/8), 1); one invocation per row.

// Keep in sync with abi::LnccTermsParams.
struct LnccTermsParams {
    dims: vec4<u32>,    // nx, ny, nz, unused
    scale: f32,         // K
    radius: u32,        // the window's radius (voxels)
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: LnccTermsParams;
@group(0) @binding(1) var<storage, read> sums: array<f32>;
@group(0) @binding(2) var<storage, read> covered: array<f32>;
@group(0) @binding(3) var<storage, read_write> terms: array<f32>;
@group(0) @binding(4) var<storage, read_write> rows: array<f32>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = vec4<u32>(params.dims.xyz, params.radius);
    let j = gid.x;
    let k = gid.y;
    if (j >= d.y || k >= d.z) {
        return;
    }
    var sum = 0.0;
    for (var i = 0u; i < d.x; i = i + 1u) {
        let v = voxel_index(i, j, k, d.xyz);
        let s = array<f32, 5>(sums[5u * v], sums[5u * v + 1u], sums[5u * v + 2u],
                              sums[5u * v + 3u], sums[5u * v + 4u]);
        let w = window_at(s, d, i, j, k);
        let kc = params.scale * select(0.0, 1.0, is_covered(covered[v]));
        var rho2 = 0.0;
        var alpha = 0.0;
        var beta = 0.0;
        if (!w.flat) {
            alpha = w.cab / (w.va * w.vb);
            beta = alpha * w.cab / w.va;
            rho2 = min(alpha * w.cab, 1.0);
        }
        sum = sum + kc * (1.0 - rho2);
        let a = kc * alpha / w.n;
        let b = kc * beta / w.n;
        terms[5u * v] = a;
        terms[5u * v + 1u] = a * w.mb;
        terms[5u * v + 2u] = b;
        terms[5u * v + 3u] = b * w.ma;
        terms[5u * v + 4u] = 0.0;
    }
    rows[j + d.y * k] = sum;
}
