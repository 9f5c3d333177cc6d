// lncc_gradient.wgsl: the image part of the local-correlation cost's gradient through the
// warp (lncc_terms.wgsl): per voxel, ∂cost/∂W · ∇I0(x + R(x)) in world mm, with
// ∂cost/∂W = −2 (T A1 − A2 − W A3 + A4) from the box-summed terms A; for lattice_splat, as
// warp_cost's gradient. Not masked by the voxel's own coverage: the windows it lies in are
// (in A), and a voxel without source data still changes the correlation of a covered window.
//
// Bindings (group 0):
//   0 uniform  RbfGradParams
//   1 storage  lattice: array<f32>    3 floats (R, mm) per lattice node
//   2 storage  moving: array<f32>     I0 on the target grid
//   3 storage  fixed: array<f32>      the target T
//   4 storage  summed: array<f32>     5 floats per voxel: A1..A4 and an unused 0
//   5 storage  gradient: array<f32>   3 floats per voxel (read_write)
// Dispatch: workgroups (ceil(ny/8), ceil(nz/8), 1); one invocation per row.

@group(0) @binding(0) var<uniform> params: RbfGradParams;
@group(0) @binding(1) var<storage, read> lattice: array<f32>;
@group(0) @binding(2) var<storage, read> moving: array<f32>;
@group(0) @binding(3) var<storage, read> fixed: array<f32>;
@group(0) @binding(4) var<storage, read> summed: array<f32>;
@group(0) @binding(5) var<storage, read_write> gradient: array<f32>;

fn sampled_value(index: u32) -> f32 {
    return moving[index];
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    let j = gid.x;
    let k = gid.y;
    if (j >= d.y || k >= d.z) {
        return;
    }
    for (var i = 0u; i < d.x; i = i + 1u) {
        let v = voxel_index(i, j, k, d.xyz);
        let s = warped_value_gradient(i, j, k);
        let t = fixed[v];
        let slope = -2.0 * (t * summed[5u * v] - summed[5u * v + 1u]
            - s.x * summed[5u * v + 2u] + summed[5u * v + 3u]);
        gradient[3u * v] = slope * s.y;
        gradient[3u * v + 1u] = slope * s.z;
        gradient[3u * v + 2u] = slope * s.w;
    }
}
