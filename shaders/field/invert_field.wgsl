// invert_field.wgsl: the inverse of a displacement field. The field u lives on grid T (the
// target's) and carries a target point x to x + u(x); its inverse w lives on grid S (the
// source's) and carries a source point y back: w(y) = z − y where z + u(z) = y. Each voxel
// solves for z, as a continuous index q of T, by Newton's method on
//   F(q) = q + M u(q) − q_y       (M: T's mm → index; q_y: y as an index of T)
// with the Jacobian I + M ∇u from the trilinear interpolant's own gradient (a fixed-point step
// where that is singular), halving a step that does not shrink |F|, from the first-order guess
// q = q_y − M u(q_y). Then w = −u(z), and the residual |z + u(z) − y| in mm is written beside
// it, or −1 where z lies outside T: y has no preimage in the target's field of view. u is read
// clamped to T (beyond its grid its edge values continue), as compose.wgsl reads it.
//
// Bindings (group 0):
//   0 uniform  InvertParams
//   1 storage  field: array<f32>     u, 3 floats per voxel of T
//   2 storage  out: array<f32>       w, 3 floats per voxel of S (read_write)
//   3 storage  residual: array<f32>  1 float per voxel of S (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)) over S.

// Keep in sync with abi::InvertParams.
struct InvertParams {
    out_dims: vec4<u32>,    // S: nx, ny, nz, unused
    field_dims: vec4<u32>,  // T: nx, ny, nz, unused
    index_to_field: array<vec4<f32>, 3>,
    mm_to_index: array<vec4<f32>, 3>,
    index_to_mm: array<vec4<f32>, 3>,
}

@group(0) @binding(0) var<uniform> params: InvertParams;
@group(0) @binding(1) var<storage, read> field: array<f32>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;
@group(0) @binding(3) var<storage, read_write> residual: array<f32>;

// Keep in sync with src/cpu/field/invert_field.rs.
const NEWTON_STEPS: u32 = 40u;
const HALVINGS: u32 = 12u;
const CONVERGED_MM: f32 = 1e-4;
const SINGULAR: f32 = 1e-6;

// The component of u that sample.wgsl reads.
var<private> component: u32;

fn sampled_value(index: u32) -> f32 {
    return field[3u * index + component];
}

// u at q (clamped into T) and its index-space gradient, one row per component.
struct Local {
    u: vec3<f32>,
    g0: vec3<f32>,
    g1: vec3<f32>,
    g2: vec3<f32>,
}

fn local_field(q: vec3<f32>) -> Local {
    let d = params.field_dims.xyz;
    let qc = clamp(q, vec3<f32>(0.0), vec3<f32>(d) - vec3<f32>(1.0));
    component = 0u;
    let a = trilinear_with_gradient(qc, d);
    component = 1u;
    let b = trilinear_with_gradient(qc, d);
    component = 2u;
    let c = trilinear_with_gradient(qc, d);
    return Local(vec3<f32>(a.x, b.x, c.x), a.yzw, b.yzw, c.yzw);
}

// M v: a displacement in mm as an index delta of T.
fn to_index(v: vec3<f32>) -> vec3<f32> {
    let m = params.mm_to_index;
    return vec3<f32>(linear_row(m[0], v), linear_row(m[1], v), linear_row(m[2], v));
}

// The length in mm of an index delta of T.
fn mm_length(f: vec3<f32>) -> f32 {
    let l = params.index_to_mm;
    return length(vec3<f32>(linear_row(l[0], f), linear_row(l[1], f), linear_row(l[2], f)));
}

// Row r of I + M ∇u.
fn jacobian_row(r: u32, unit: vec3<f32>, at: Local) -> vec3<f32> {
    let m = params.mm_to_index[r];
    return unit + m.x * at.g0 + m.y * at.g1 + m.z * at.g2;
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.out_dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let p = vec3<f32>(f32(gid.x), f32(gid.y), f32(gid.z));
    let t = params.index_to_field;
    let qy = vec3<f32>(affine_row(t[0], p), affine_row(t[1], p), affine_row(t[2], p));
    var q = qy - to_index(local_field(qy).u);
    var at = local_field(q);
    var f = q + to_index(at.u) - qy;
    var size = mm_length(f);
    for (var step = 0u; step < NEWTON_STEPS && size >= CONVERGED_MM; step = step + 1u) {
        let r0 = jacobian_row(0u, vec3<f32>(1.0, 0.0, 0.0), at);
        let r1 = jacobian_row(1u, vec3<f32>(0.0, 1.0, 0.0), at);
        let r2 = jacobian_row(2u, vec3<f32>(0.0, 0.0, 1.0), at);
        let det = det3(r0, r1, r2);
        var delta = -f;
        if (abs(det) > SINGULAR) {
            delta = solve3(r0, r1, r2, det, -f);
        }
        var shrunk = false;
        var scale = 1.0;
        for (var h = 0u; h < HALVINGS && !shrunk; h = h + 1u) {
            let qn = q + scale * delta;
            let an = local_field(qn);
            let fq = qn + to_index(an.u) - qy;
            let sn = mm_length(fq);
            if (sn < size) {
                q = qn;
                at = an;
                f = fq;
                size = sn;
                shrunk = true;
            }
            scale = 0.5 * scale;
        }
        if (!shrunk) {
            break;
        }
    }
    let o = 3u * voxel_index(gid.x, gid.y, gid.z, d.xyz);
    out[o] = -at.u.x;
    out[o + 1u] = -at.u.y;
    out[o + 2u] = -at.u.z;
    var r = -1.0;
    if (inside_source(q, params.field_dims.xyz)) {
        r = size;
    }
    residual[voxel_index(gid.x, gid.y, gid.z, d.xyz)] = r;
}
