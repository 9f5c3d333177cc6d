// rigid_score.wgsl: scores many candidate rigid motions of one bone in one pass (the coarse
// rotation search that starts each bone inside descent's reach).
//
// For candidate c (a world -> world 3x4 matrix M_c) and each source voxel x in the bone region
// (mask >= 0.5) whose moved point lies inside the target: Σ (T(M_c x) - S(x))², the count, and
// Σ S, Σ T, Σ S², Σ T², Σ S·T for the correlation of the bone with the target there.
// One invocation owns one (x, z) column for one candidate and walks it along y.
//
// Bindings (group 0):
//   0 uniform  ScoreParams
//   1 storage  source: array<f32>      the source level
//   2 storage  mask: array<f32>        the bone-region mask
//   3 storage  target_image: array<f32>      the target level
//   4 storage  candidates: array<f32>  12 floats (3 rows of 4) per candidate
//   5 storage  partial: array<f32>     SCORE_SUMS (7) per column and candidate (read_write):
//                                      from index ((z * nx + x) * candidates + c) * 7, in the
//                                      order Σr², count, ΣS, ΣT, ΣS², ΣT², ΣST (abi::SCORE_SUMS)
// Dispatch: workgroups (ceil(nx/64), nz, candidates).

// Keep in sync with abi::ScoreParams.
struct ScoreParams {
    dims: vec4<u32>,          // source nx, ny, nz, unused
    target_dims: vec4<u32>,   // target nx, ny, nz, unused
    source_to_world: array<vec4<f32>, 3>,
    world_to_target: array<vec4<f32>, 3>,
    candidates: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: ScoreParams;
@group(0) @binding(1) var<storage, read> source: array<f32>;
@group(0) @binding(2) var<storage, read> mask: array<f32>;
@group(0) @binding(3) var<storage, read> target_image: array<f32>;
@group(0) @binding(4) var<storage, read> candidates: array<f32>;
@group(0) @binding(5) var<storage, read_write> partial: array<f32>;

fn sampled_value(index: u32) -> f32 {
    return target_image[index];
}

fn candidate_row(c: u32, r: u32) -> vec4<f32> {
    let b = c * 12u + r * 4u;
    return vec4<f32>(candidates[b], candidates[b + 1u], candidates[b + 2u], candidates[b + 3u]);
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nx = params.dims.x;
    let ny = params.dims.y;
    let count = params.candidates;
    let x = gid.x;
    let z = gid.y;
    let c = gid.z;
    if (x >= nx || z >= params.dims.z || c >= count) {
        return;
    }
    let m0 = candidate_row(c, 0u);
    let m1 = candidate_row(c, 1u);
    let m2 = candidate_row(c, 2u);
    let tdims = params.target_dims.xyz;
    var sum = 0.0;
    var n = 0.0;
    var s1 = 0.0;
    var t1 = 0.0;
    var s2 = 0.0;
    var t2 = 0.0;
    var st = 0.0;
    for (var y = 0u; y < ny; y = y + 1u) {
        let i = voxel_index(x, y, z, params.dims.xyz);
        if (mask[i] < 0.5) {
            continue;
        }
        let p = vec3<f32>(f32(x), f32(y), f32(z));
        let w = vec3<f32>(
            affine_row(params.source_to_world[0], p),
            affine_row(params.source_to_world[1], p),
            affine_row(params.source_to_world[2], p),
        );
        let moved = vec3<f32>(affine_row(m0, w), affine_row(m1, w), affine_row(m2, w));
        let q = vec3<f32>(
            affine_row(params.world_to_target[0], moved),
            affine_row(params.world_to_target[1], moved),
            affine_row(params.world_to_target[2], moved),
        );
        if (!inside_source(q, tdims)) {
            continue;
        }
        let t = trilinear(q, tdims, 0.0);
        let s = source[i];
        let r = t - s;
        sum = sum + r * r;
        n = n + 1.0;
        s1 = s1 + s;
        t1 = t1 + t;
        s2 = s2 + s * s;
        t2 = t2 + t * t;
        st = st + s * t;
    }
    let base = ((z * nx + x) * count + c) * 7u;
    partial[base] = sum;
    partial[base + 1u] = n;
    partial[base + 2u] = s1;
    partial[base + 3u] = t1;
    partial[base + 4u] = s2;
    partial[base + 5u] = t2;
    partial[base + 6u] = st;
}
