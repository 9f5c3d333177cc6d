// dense_force.wgsl: the dense stage's force at every target voxel: the direction in which
// moving the warped source W (the source seen through the whole field) improves its match
// with the target F, before smoothing; and the voxel's cost. Updating the map x → ψ(x) to
// ψ(x + δ(x)) changes W(x) to W(x + δ) ≈ W + ∇W · δ, so a term's derivative with respect to
// W(x) times ∇W is its gradient with respect to δ(x) (the demons / greedy force).
//   SSD:  force = c (F − W) ∇W                    cost = c (W − F)²
//   LNCC: force = c 2 σ_WF / (σ_W² σ_F²) ((F − μ_F) − σ_WF / σ_W² (W − μ_W)) ∇W
//         cost = 1 − c ρ², ρ = σ_WF / (σ_W σ_F) over the voxel's window (ANTs' and greedy's
//         form: the window centred on the voxel only; ρ = 0 where a window is flat, as in
//         ANTs, so that flattening a window or leaving the source never lowers the cost)
//   Volume: W = det J of the whole map ψ (F unused), ℓ = log max(W, VOLUME_DET_FLOOR):
//         force = c 2 (1 − ℓ) ∇W / max(W, VOLUME_DET_FLOOR)   cost = c ℓ²
//         (updating ψ to ψ(x + δ) makes ℓ ℓ(x + δ) + div δ to first order; the force is the
//         negative gradient of Σ ℓ² with respect to δ, the divergence's adjoint −∇: real soft
//         tissue keeps its volume, which the image term alone does not ask)
// c is 1 where the field's point lies inside the source (coverage ≥ abi::COVERED_AT), else 0.
// ∇W is in world mm: central differences along the index axes (one-sided at the faces)
// times d(index)/d(world), as fold/jacobian.wgsl differentiates a field.
//
// Bindings (group 0):
//   0 uniform  ForceParams
//   1 storage  moving: array<f32>    W, 1 float per voxel
//   2 storage  fixed: array<f32>     F, 1 float per voxel
//   3 storage  covered: array<f32>   c, 1 float per voxel
//   4 storage  sums: array<f32>      LNCC: the box sums of (W, F), local_moments' last pass,
//                                    5 floats per voxel; SSD: unused (any buffer)
//   5 storage  force: array<f32>     3 floats per voxel (read_write)
//   6 storage  cost: array<f32>      1 float per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::dense::ForceParams.
struct ForceParams {
    nx: u32,
    ny: u32,
    nz: u32,
    radius: u32,     // LNCC's window radius (voxels)
    term: u32,       // 0 SSD, 1 LNCC, 2 volume
    pad0: u32,
    pad1: u32,
    pad2: u32,
    mm_to_index: array<vec4<f32>, 3>,
}

// Keep in sync with abi::dense::VOLUME_DET_FLOOR.
const VOLUME_DET_FLOOR: f32 = 0.5;

@group(0) @binding(0) var<uniform> params: ForceParams;
@group(0) @binding(1) var<storage, read> moving: array<f32>;
@group(0) @binding(2) var<storage, read> fixed: array<f32>;
@group(0) @binding(3) var<storage, read> covered: array<f32>;
@group(0) @binding(4) var<storage, read> sums: array<f32>;
@group(0) @binding(5) var<storage, read_write> force: array<f32>;
@group(0) @binding(6) var<storage, read_write> cost: array<f32>;

// Central difference of W along one axis at coordinate c of n (one-sided at the ends).
fn slope(lo: f32, hi: f32, c: u32, n: u32) -> f32 {
    if (n == 1u) {
        return 0.0;
    }
    if (c == 0u || c == n - 1u) {
        return hi - lo;
    }
    return (hi - lo) * 0.5;
}

// ∇W at voxel (i, j, k), world mm.
fn gradient(i: u32, j: u32, k: u32, d: vec3<u32>) -> vec3<f32> {
    let gx = slope(moving[voxel_index(max(i, 1u) - 1u, j, k, d)],
                   moving[voxel_index(min(i + 1u, d.x - 1u), j, k, d)], i, d.x);
    let gy = slope(moving[voxel_index(i, max(j, 1u) - 1u, k, d)],
                   moving[voxel_index(i, min(j + 1u, d.y - 1u), k, d)], j, d.y);
    let gz = slope(moving[voxel_index(i, j, max(k, 1u) - 1u, d)],
                   moving[voxel_index(i, j, min(k + 1u, d.z - 1u), d)], k, d.z);
    return gx * params.mm_to_index[0].xyz + gy * params.mm_to_index[1].xyz
        + gz * params.mm_to_index[2].xyz;
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = vec3<u32>(params.nx, params.ny, params.nz);
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let c = select(0.0, 1.0, is_covered(covered[v]));
    let w = moving[v];
    let f = fixed[v];
    var along = c * (f - w);
    var term = c * (w - f) * (w - f);
    if (params.term == 1u) {
        // local_moments summed a = W and b = F.
        let s = array<f32, 5>(sums[5u * v], sums[5u * v + 1u], sums[5u * v + 2u],
                              sums[5u * v + 3u], sums[5u * v + 4u]);
        let win = window_at(s, vec4<u32>(d, params.radius), gid.x, gid.y, gid.z);
        along = 0.0;
        term = 1.0;
        if (!win.flat) {
            let spread = win.va * win.vb;
            along = c * (2.0 * win.cab / spread) * ((f - win.mb) - win.cab / win.va * (w - win.ma));
            term = 1.0 - c * (win.cab * win.cab / spread);
        }
    }
    if (params.term == 2u) {
        let det = max(w, VOLUME_DET_FLOOR);
        let l = log(det);
        along = c * 2.0 * (1.0 - l) / det;
        term = c * l * l;
    }
    let g = gradient(gid.x, gid.y, gid.z, d);
    force[3u * v] = along * g.x;
    force[3u * v + 1u] = along * g.y;
    force[3u * v + 2u] = along * g.z;
    cost[v] = term;
}
