// stencil.wgsl: the jacobian kernel's finite-difference stencil at one voxel, with det J's
// gradient: prepended to the fold push's kernels (fold_push, fold_refresh), whose `params` have
// the grid's `dims` and `mm_to_index` rows and which bind the displacement field as `field`.
// Mirrored in src/cpu/fold/stencil.rs. det3 of the same rows as jacobian.wgsl, so a voxel's
// determinant here is the jacobian kernel's.

fn displacement(v: u32) -> vec3<f32> {
    return vec3<f32>(field[3u * v], field[3u * v + 1u], field[3u * v + 2u]);
}

// The neighbours the jacobian kernel differences along one axis at a voxel, and the factor on
// their difference: central inside, one-sided on a face (the voxel itself on the other side).
struct Arm {
    lo: u32,
    hi: u32,
    factor: f32,
}

fn arm(c: vec3<u32>, v: u32, axis: u32) -> Arm {
    let d = params.dims.xyz;
    let stride = vec3<u32>(1u, d.x, d.x * d.y);
    let has_lo = c[axis] > 0u;
    let has_hi = c[axis] + 1u < d[axis];
    return Arm(select(v, v - stride[axis], has_lo), select(v, v + stride[axis], has_hi),
               select(1.0, 0.5, has_lo && has_hi));
}

fn cross3(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y);
}

fn dot3(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

// det J at voxel v (det3, as the jacobian kernel) and, in columns 0..2, its gradient with
// respect to the difference along each index axis: d det = tr(adj(J) dD G), so the gradient
// for column a of D is cof(J) . G_a.
struct DetGradient {
    det: f32,
    gradient: array<vec3<f32>, 3>,
}

// The rows of J = I + du/dx at voxel v, as the jacobian kernel forms them.
fn jacobian_rows(c: vec3<u32>, v: u32) -> array<vec3<f32>, 3> {
    var d: array<vec3<f32>, 3>;
    for (var a = 0u; a < 3u; a = a + 1u) {
        let s = arm(c, v, a);
        d[a] = (displacement(s.hi) - displacement(s.lo)) * s.factor;
    }
    let g0 = params.mm_to_index[0].xyz;
    let g1 = params.mm_to_index[1].xyz;
    let g2 = params.mm_to_index[2].xyz;
    return array<vec3<f32>, 3>(
        g0 * d[0].x + g1 * d[1].x + g2 * d[2].x + vec3<f32>(1.0, 0.0, 0.0),
        g0 * d[0].y + g1 * d[1].y + g2 * d[2].y + vec3<f32>(0.0, 1.0, 0.0),
        g0 * d[0].z + g1 * d[1].z + g2 * d[2].z + vec3<f32>(0.0, 0.0, 1.0),
    );
}

// det J at voxel v alone.
fn det_at(c: vec3<u32>, v: u32) -> f32 {
    let r = jacobian_rows(c, v);
    return det3(r[0], r[1], r[2]);
}

fn det_and_gradient(c: vec3<u32>, v: u32) -> DetGradient {
    let r = jacobian_rows(c, v);
    let g0 = params.mm_to_index[0].xyz;
    let g1 = params.mm_to_index[1].xyz;
    let g2 = params.mm_to_index[2].xyz;
    let c0 = cross3(r[1], r[2]);
    let c1 = cross3(r[2], r[0]);
    let c2 = cross3(r[0], r[1]);
    var out: DetGradient;
    out.det = det3(r[0], r[1], r[2]);
    out.gradient[0] = vec3<f32>(dot3(c0, g0), dot3(c1, g0), dot3(c2, g0));
    out.gradient[1] = vec3<f32>(dot3(c0, g1), dot3(c1, g1), dot3(c2, g1));
    out.gradient[2] = vec3<f32>(dot3(c0, g2), dot3(c1, g2), dot3(c2, g2));
    return out;
}

fn voxel_of(v: u32) -> vec3<u32> {
    let d = params.dims.xyz;
    return vec3<u32>(v % d.x, (v / d.x) % d.y, v / (d.x * d.y));
}

