// rbf_lattice.wgsl: the cubic-RBF warp R at every node of the non-rigid stage's lattice, in f64.
//
// R(x) = a0 + a1 x + a2 y + a3 z + Σ_i λ_i |x − c_i|³. Its terms are up to a million times
// larger than R itself (the λ_i cancel: Σ λ_i = 0, Σ λ_i c_i = 0), so f32 loses R to
// rounding (0.05 mm measured at 183 points); f64 keeps it. The sum runs in the order
// RbfCoefficients::eval_many uses on the host: the affine part, then the points in order.
//
// Bindings (group 0):
//   0 uniform  RbfLatticeParams
//   1 storage  geometry: array<f64>  rows of the target grid's voxel → world affine, 3 × 4
//   2 storage  spline: array<f64>    affine a[k][c] at 3k + c (12), then per point
//                                    (cx, cy, cz, λx, λy, λz)
//   3 storage  values: array<f32>    3 floats (R, mm) per node (read_write)
// Dispatch: workgroups (ceil(lx/4), ceil(ly/4), ceil(lz/4)).

@group(0) @binding(0) var<uniform> params: RbfLatticeParams;
@group(0) @binding(1) var<storage, read> geometry: array<f64>;
@group(0) @binding(2) var<storage, read> spline: array<f64>;
@group(0) @binding(3) var<storage, read_write> values: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let l = params.lattice;
    if (gid.x >= l.x || gid.y >= l.y || gid.z >= l.z) {
        return;
    }
    let x = node_position(gid, params.step.xyz);
    var r = vec3<f64>(
        spline[0] + spline[3] * x.x + spline[6] * x.y + spline[9] * x.z,
        spline[1] + spline[4] * x.x + spline[7] * x.y + spline[10] * x.z,
        spline[2] + spline[5] * x.x + spline[8] * x.y + spline[11] * x.z,
    );
    for (var p = 0u; p < params.points; p = p + 1u) {
        let o = 12u + 6u * p;
        let f = cube_of_distance(x, vec3<f64>(spline[o], spline[o + 1u], spline[o + 2u]));
        r = r + vec3<f64>(spline[o + 3u] * f, spline[o + 4u] * f, spline[o + 5u] * f);
    }
    let n = 3u * voxel_index(gid.x, gid.y, gid.z, l.xyz);
    values[n] = f32(r.x);
    values[n + 1u] = f32(r.y);
    values[n + 2u] = f32(r.z);
}
