// rbf_adjoint.wgsl: the adjoint of rbf_lattice — the gradient of the cost with respect to the
// RBF's coefficients, from its gradient G with respect to the warp at each lattice node, in
// f64 (the terms cancel as in rbf_lattice). For control point i: Σ_n φ(|x_n − c_i|) G_n; for
// the affine part (4 rows): Σ_n G_n, Σ_n x_n G_n, Σ_n y_n G_n, Σ_n z_n G_n.
// RbfSystem::value_gradient turns the result into the gradient with respect to the control
// values.
//
// The nodes are split into chunks of params.chunks.y; each invocation sums one chunk for one
// output row, in node order, and sum_partials adds the chunks in order. (One invocation over
// every node was wrong on lavapipe: llvmpipe ends any loop after 65 535 iterations.)
//
// Bindings (group 0):
//   0 uniform  RbfLatticeParams
//   1 storage  geometry: array<f64>       as rbf_lattice
//   2 storage  spline: array<f64>         as rbf_lattice (only the point positions are read)
//   3 storage  node_gradient: array<f32>  3 floats per node
//   4 storage  partials: array<f64>       per chunk c, per output row t (points, then 4
//                                         affine rows): 3 values at 3 (c rows + t)
//                                         (read_write)
// Dispatch: workgroups (ceil((points + 4) / 64), chunks, 1).

@group(0) @binding(0) var<uniform> params: RbfLatticeParams;
@group(0) @binding(1) var<storage, read> geometry: array<f64>;
@group(0) @binding(2) var<storage, read> spline: array<f64>;
@group(0) @binding(3) var<storage, read> node_gradient: array<f32>;
@group(0) @binding(4) var<storage, read_write> partials: array<f64>;

fn gradient_at(n: u32) -> vec3<f64> {
    return vec3<f64>(
        f64(node_gradient[3u * n]),
        f64(node_gradient[3u * n + 1u]),
        f64(node_gradient[3u * n + 2u]),
    );
}

// The weight of node x in output row t: φ(|x − c_t|) for a control point, else the affine
// row's term 1, x, y or z.
fn weight(t: u32, x: vec3<f64>) -> f64 {
    let points = params.points;
    if (t < points) {
        let o = 12u + 6u * t;
        return cube_of_distance(x, vec3<f64>(spline[o], spline[o + 1u], spline[o + 2u]));
    }
    let k = t - points;
    if (k == 0u) {
        return 1.0lf;
    }
    return x[k - 1u];
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = gid.x;
    let c = gid.y;
    let rows = params.points + 4u;
    if (t >= rows || c >= params.chunks.z) {
        return;
    }
    let l = params.lattice.xyz;
    let nodes = params.chunks.x;
    let per_chunk = params.chunks.y;
    var sum = vec3<f64>(0.0lf);
    for (var n = c * per_chunk; n < min((c + 1u) * per_chunk, nodes); n = n + 1u) {
        let a = vec3<u32>(n % l.x, (n / l.x) % l.y, n / (l.x * l.y));
        let x = node_position(a, params.step.xyz);
        let g = gradient_at(n);
        let w = weight(t, x);
        sum = sum + vec3<f64>(g.x * w, g.y * w, g.z * w);
    }
    let o = 3u * (c * rows + t);
    partials[o] = sum.x;
    partials[o + 1u] = sum.y;
    partials[o + 2u] = sum.z;
}
