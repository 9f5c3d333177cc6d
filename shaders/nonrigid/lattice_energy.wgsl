// lattice_energy.wgsl: the smoothness energy of the lattice warp and the whole cost's gradient
// with respect to the warp at each node.
//
// The energy is a sum of quadratic operators placed wherever all their taps fall on the
// lattice (crate::regularise: first differences for the membrane, second for bending), each
// result's squared length weighted: E = Σ_o w_o Σ_p |Σ_t c_ot R(p + t)|². Per node n this
// kernel writes the energy of the placements anchored at n (summed by sum_chunks), and the
// image gradient splatted to n (lattice_splat, scaled by params.scale = 1 / voxels) plus
// ∂E/∂R(n) = Σ 2 w_o c_ot (result at p = n − t), gathered over the placements that touch n so
// no atomics are needed.
//
// Bindings (group 0):
//   0 uniform  EnergyParams
//   1 storage  lattice: array<f32>   3 floats (R, mm) per node
//   2 storage  splat: array<f32>     3 floats per node (lattice_splat's output)
//   3 storage  gradient: array<f32>  3 floats per node (read_write)
//   4 storage  energy: array<f32>    1 float per node (read_write)
// Dispatch: workgroups (ceil(lx/4), ceil(ly/4), ceil(lz/4)).

// Keep in sync with abi::EnergyParams.
struct EnergyParams {
    dims: vec4<u32>,                       // lx, ly, lz, unused
    scale: f32,                            // factor on the splatted image gradient
    operators: u32,                        // at most 9
    pad0: u32,
    pad1: u32,
    taps: array<vec4<i32>, 36>,            // operator o's tap t at 4 o + t: offset, unused
    coefficients: array<vec4<f32>, 9>,     // operator o's tap coefficients
    weights: array<vec4<f32>, 9>,          // operator o's weight, unused x3
    tap_counts: array<vec4<u32>, 3>,       // operator o's taps at [o / 4][o % 4]
}

@group(0) @binding(0) var<uniform> params: EnergyParams;
@group(0) @binding(1) var<storage, read> lattice: array<f32>;
@group(0) @binding(2) var<storage, read> splat: array<f32>;
@group(0) @binding(3) var<storage, read_write> gradient: array<f32>;
@group(0) @binding(4) var<storage, read_write> energy: array<f32>;

fn tap_count(o: u32) -> u32 {
    return params.tap_counts[o / 4u][o % 4u];
}

// Whether every tap of operator o placed at p lies on the lattice.
fn placed(o: u32, p: vec3<i32>) -> bool {
    let top = vec3<i32>(params.dims.xyz);
    for (var t = 0u; t < tap_count(o); t = t + 1u) {
        let q = p + params.taps[4u * o + t].xyz;
        if (any(q < vec3<i32>(0)) || any(q >= top)) {
            return false;
        }
    }
    return true;
}

// Σ_t c_ot R(p + t) for a placement that lies on the lattice.
fn result_at(o: u32, p: vec3<i32>) -> vec3<f32> {
    var sum = vec3<f32>(0.0);
    for (var t = 0u; t < tap_count(o); t = t + 1u) {
        let q = vec3<u32>(p + params.taps[4u * o + t].xyz);
        let n = 3u * voxel_index(q.x, q.y, q.z, params.dims.xyz);
        let r = vec3<f32>(lattice[n], lattice[n + 1u], lattice[n + 2u]);
        sum = sum + params.coefficients[o][t] * r;
    }
    return sum;
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let here = vec3<i32>(gid);
    let n = voxel_index(gid.x, gid.y, gid.z, d.xyz);
    var g = params.scale * vec3<f32>(splat[3u * n], splat[3u * n + 1u], splat[3u * n + 2u]);
    var e = 0.0;
    for (var o = 0u; o < params.operators; o = o + 1u) {
        let w = params.weights[o].x;
        if (placed(o, here)) {
            let r = result_at(o, here);
            e = e + w * dot(r, r);
        }
        for (var t = 0u; t < tap_count(o); t = t + 1u) {
            let p = here - params.taps[4u * o + t].xyz;
            if (placed(o, p)) {
                g = g + (2.0 * w * params.coefficients[o][t]) * result_at(o, p);
            }
        }
    }
    gradient[3u * n] = g.x;
    gradient[3u * n + 1u] = g.y;
    gradient[3u * n + 2u] = g.z;
    energy[n] = e;
}
