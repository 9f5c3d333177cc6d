// skin_blend.wgsl: volume skeletal deformation (paper eq. 1) inverted for pull-back resampling.
//
// The blend maps a source point x to B(x) = Σ_j w_j(x) M_j x (linear blend skinning of the
// whole volume), or with blending 1 to D(x) x where D(x) is the normalised blend Σ_j w_j(x) q_j
// of the motions' unit dual quaternions (a rigid motion again; see src/vsd.rs). Inside a bone (nearest voxel of the source label grid) the weights are that
// bone's alone, so bones move exactly rigidly up to their labelled surface; elsewhere w_j is
// trilinear from the coarser weight grid, clamped to its edge. For each target voxel
// p this finds the source point x with B(x) = p: start from the bone whose inverse M_j⁻¹ p
// blends back closest to p, then Newton-like steps x ← x − t A(x)⁻¹ (B(x) − p) with
// A = Σ_j w_j L_j (the blended linear part; the weights' own derivative is left out, which keeps
// each step a 3×3 solve) and t the first of 1, 1/2, ... 1/16 that lowers the miss.
// Output per voxel: u = x − p (the initial displacement field, world mm) and the residual
// |B(x) − p| (mm): where it is not small the blend was not inverted (it folds there).
//
// Bindings (group 0):
//   0 uniform  SkinBlendParams (bone matrices for up to 8 bones)
//   1 storage  weight: array<f32>  bones floats per voxel of the weight grid, whole
//   2 storage  bone_of_voxel: array<f32>  per source label voxel: 1 + the bone's index, or 0
//   3 storage  field: array<f32>     3 floats per target voxel: u (read_write)
//   4 storage  residual: array<f32>  1 float per target voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)) over the target grid.

// Keep in sync with abi::SkinBlendParams.
struct SkinBlendParams {
    dims: vec4<u32>,        // target nx, ny, nz, unused
    bones: u32,
    iterations: u32,        // most iterations of the inversion
    blending: u32,          // 0 linear, 1 dual quaternion
    pad0: u32,
    weight_dims: vec4<u32>, // weight grid nx, ny, nz, unused
    label_dims: vec4<u32>,  // source label grid nx, ny, nz, unused
    target_to_world: array<vec4<f32>, 3>,
    world_to_weight: array<vec4<f32>, 3>,
    world_to_label: array<vec4<f32>, 3>,
    forward: array<vec4<f32>, 24>,   // 3 rows of M_j per bone
    inverse: array<vec4<f32>, 24>,   // 3 rows of M_j⁻¹ per bone
    dual: array<vec4<f32>, 16>,      // unit dual quaternion of M_j per bone: real, dual (x, y, z, w)
}

@group(0) @binding(0) var<uniform> params: SkinBlendParams;

// A voxel whose blend lands within this of its target point needs no more steps (mm): a
// thousandth of a millimetre, far below any registration's error; the steps converge
// linearly (the weights' derivative is left out), and 1e-4 took a quarter longer (half phantom
// 60°: 2.04 against 1.62 s).
const CONVERGED_MM: f32 = 1e-3;
@group(0) @binding(1) var<storage, read> weight: array<f32>;
@group(0) @binding(2) var<storage, read> bone_of_voxel: array<f32>;
@group(0) @binding(3) var<storage, read_write> field: array<f32>;
@group(0) @binding(4) var<storage, read_write> residual: array<f32>;

struct Blend {
    point: vec3<f32>,  // B(x)
    r0: vec3<f32>,     // rows of A(x)
    r1: vec3<f32>,
    r2: vec3<f32>,
}

// sample.wgsl's nearest reads the source label voxels' bone indices.
fn sampled_value(index: u32) -> f32 {
    return bone_of_voxel[index];
}

// The bone whose label holds x (nearest label voxel), or `bones` when x is in soft tissue or
// outside the label grid.
fn bone_at(x: vec3<f32>) -> u32 {
    let bones = params.bones;
    let n = params.label_dims.xyz;
    let q = vec3<f32>(
        affine_row(params.world_to_label[0], x),
        affine_row(params.world_to_label[1], x),
        affine_row(params.world_to_label[2], x),
    );
    let b = u32(nearest(q, n, 0.0));
    return select(bones, b - 1u, b > 0u);
}

fn blend(x: vec3<f32>) -> Blend {
    let n = params.weight_dims.xyz;
    let bones = params.bones;
    let inside = bone_at(x);
    if (inside < bones) {
        let m0 = params.forward[3u * inside];
        let m1 = params.forward[3u * inside + 1u];
        let m2 = params.forward[3u * inside + 2u];
        var rigid: Blend;
        rigid.point = vec3<f32>(affine_row(m0, x), affine_row(m1, x), affine_row(m2, x));
        rigid.r0 = m0.xyz;
        rigid.r1 = m1.xyz;
        rigid.r2 = m2.xyz;
        return rigid;
    }
    let s = vec3<f32>(
        affine_row(params.world_to_weight[0], x),
        affine_row(params.world_to_weight[1], x),
        affine_row(params.world_to_weight[2], x),
    );
    let q = clamp(s, vec3<f32>(0.0), vec3<f32>(n - vec3<u32>(1u)));
    let base = floor(q);
    let t = q - base;
    let i0 = vec3<u32>(base);
    let i1 = min(i0 + vec3<u32>(1u), n - vec3<u32>(1u));
    var b: Blend;
    b.point = vec3<f32>(0.0);
    b.r0 = vec3<f32>(0.0);
    b.r1 = vec3<f32>(0.0);
    b.r2 = vec3<f32>(0.0);
    let dual_quaternion = params.blending == 1u;
    var real = vec4<f32>(0.0);
    var dual = vec4<f32>(0.0);
    for (var j = 0u; j < bones; j = j + 1u) {
        let v000 = weight[voxel_index(i0.x, i0.y, i0.z, n) * bones + j];
        let v100 = weight[voxel_index(i1.x, i0.y, i0.z, n) * bones + j];
        let v010 = weight[voxel_index(i0.x, i1.y, i0.z, n) * bones + j];
        let v110 = weight[voxel_index(i1.x, i1.y, i0.z, n) * bones + j];
        let v001 = weight[voxel_index(i0.x, i0.y, i1.z, n) * bones + j];
        let v101 = weight[voxel_index(i1.x, i0.y, i1.z, n) * bones + j];
        let v011 = weight[voxel_index(i0.x, i1.y, i1.z, n) * bones + j];
        let v111 = weight[voxel_index(i1.x, i1.y, i1.z, n) * bones + j];
        let c00 = (1.0 - t.x) * v000 + t.x * v100;
        let c10 = (1.0 - t.x) * v010 + t.x * v110;
        let c01 = (1.0 - t.x) * v001 + t.x * v101;
        let c11 = (1.0 - t.x) * v011 + t.x * v111;
        let c0 = (1.0 - t.y) * c00 + t.y * c10;
        let c1 = (1.0 - t.y) * c01 + t.y * c11;
        let w = (1.0 - t.z) * c0 + t.z * c1;
        if (dual_quaternion) {
            real = real + w * params.dual[2u * j];
            dual = dual + w * params.dual[2u * j + 1u];
        } else {
            let m0 = params.forward[3u * j];
            let m1 = params.forward[3u * j + 1u];
            let m2 = params.forward[3u * j + 2u];
            b.point = b.point + w * vec3<f32>(affine_row(m0, x), affine_row(m1, x), affine_row(m2, x));
            b.r0 = b.r0 + w * m0.xyz;
            b.r1 = b.r1 + w * m1.xyz;
            b.r2 = b.r2 + w * m2.xyz;
        }
    }
    if (dual_quaternion) {
        return dual_quaternion_motion(real, dual, x);
    }
    return b;
}

// The rigid motion of the blended dual quaternion (real, dual), applied to x: normalised by the
// real part's length, rotation from the real part, translation 2 (dual · conj(real)).
fn dual_quaternion_motion(real_sum: vec4<f32>, dual_sum: vec4<f32>, x: vec3<f32>) -> Blend {
    let norm = length(real_sum);
    let r = real_sum / norm;
    let d = dual_sum / norm;
    let t = 2.0 * (r.w * d.xyz - d.w * r.xyz + cross(r.xyz, d.xyz));
    var b: Blend;
    b.r0 = vec3<f32>(1.0 - 2.0 * (r.y * r.y + r.z * r.z), 2.0 * (r.x * r.y - r.z * r.w), 2.0 * (r.x * r.z + r.y * r.w));
    b.r1 = vec3<f32>(2.0 * (r.x * r.y + r.z * r.w), 1.0 - 2.0 * (r.x * r.x + r.z * r.z), 2.0 * (r.y * r.z - r.x * r.w));
    b.r2 = vec3<f32>(2.0 * (r.x * r.z - r.y * r.w), 2.0 * (r.y * r.z + r.x * r.w), 1.0 - 2.0 * (r.x * r.x + r.y * r.y));
    b.point = vec3<f32>(dot(b.r0, x), dot(b.r1, x), dot(b.r2, x)) + t;
    return b;
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let bones = params.bones;
    let v = vec3<f32>(f32(gid.x), f32(gid.y), f32(gid.z));
    let p = vec3<f32>(
        affine_row(params.target_to_world[0], v),
        affine_row(params.target_to_world[1], v),
        affine_row(params.target_to_world[2], v),
    );
    var x = p;
    var best = 3.4e38;
    // The blend at x, kept from where x was chosen: each step reuses it instead of blending
    // again at the same point.
    var b: Blend;
    for (var j = 0u; j < bones; j = j + 1u) {
        let candidate = vec3<f32>(
            affine_row(params.inverse[3u * j], p),
            affine_row(params.inverse[3u * j + 1u], p),
            affine_row(params.inverse[3u * j + 2u], p),
        );
        let at = blend(candidate);
        let miss = length(at.point - p);
        if (miss < best) {
            best = miss;
            x = candidate;
            b = at;
        }
    }
    if (best == 3.4e38) {
        // No candidate's miss was finite: step from the blend at p itself.
        b = blend(x);
    }
    var err = best;
    for (var it = 0u; it < params.iterations && err > CONVERGED_MM; it = it + 1u) {
        let e = b.point - p;
        let det = det3(b.r0, b.r1, b.r2);
        var step = e;
        if (abs(det) > 1e-6) {
            step = solve3(b.r0, b.r1, b.r2, det, e);
        }
        // Backtrack: where the weights change fast the full step overshoots and would oscillate
        // between two sides of the solution; take the first fraction that lowers the miss.
        var t = 1.0;
        var moved = false;
        for (var k = 0u; k < 5u && !moved; k = k + 1u) {
            let trial = x - t * step;
            let at = blend(trial);
            let miss = length(at.point - p);
            if (miss < err) {
                x = trial;
                err = miss;
                b = at;
                moved = true;
            }
            t = t * 0.5;
        }
        if (!moved) {
            break;
        }
    }
    let o = voxel_index(gid.x, gid.y, gid.z, d.xyz);
    field[3u * o] = x.x - p.x;
    field[3u * o + 1u] = x.y - p.y;
    field[3u * o + 2u] = x.z - p.z;
    residual[o] = err;
}
