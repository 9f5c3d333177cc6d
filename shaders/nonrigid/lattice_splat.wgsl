// lattice_splat.wgsl: the adjoint of rbf_grad's lattice interpolation. A voxel's value reaches
// the lattice nodes of its cell with the trilinear weights it was interpolated with, so the
// gradient of the cost with respect to the warp at node n is Σ_x w_n(x) g(x). Written as a
// gather (each node sums the voxels within one lattice step along each axis), so no atomics
// are needed and the sum order is fixed.
//
// Bindings (group 0):
//   0 uniform  SplatParams
//   1 storage  values: array<f32>  3 floats per voxel of the target grid, whole
//   2 storage  out: array<f32>     3 floats per lattice node (read_write)
// Dispatch: workgroups (ceil(lx/4), ceil(ly/4), ceil(lz/4)) over the lattice.

// Keep in sync with abi::SplatParams.
struct SplatParams {
    dims: vec4<u32>,          // lattice lx, ly, lz, unused
    step: vec4<u32>,          // lattice step along x, y, z (voxels), unused
    volume_dims: vec4<u32>,   // target nx, ny, nz, unused
}

@group(0) @binding(0) var<uniform> params: SplatParams;
@group(0) @binding(1) var<storage, read> values: array<f32>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;

// Voxels along one axis that node a reaches, and the weight of voxel v: 1 − |v/s − a| clamped.
fn reach_lo(a: u32, s: u32) -> u32 {
    return select(0u, (a - 1u) * s + 1u, a > 0u);
}

fn weight(v: u32, a: u32, s: u32) -> f32 {
    return max(0.0, 1.0 - abs(f32(v) / f32(s) - f32(a)));
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let s = params.step.xyz;
    let n = params.volume_dims.xyz;
    let a = vec3<u32>(gid.x, gid.y, gid.z);
    var sum = vec3<f32>(0.0);
    // The lattice covers the grid (its last node sits at or beyond the last voxel), so every
    // voxel lies between two nodes and these weights are exactly rbf_grad's.
    for (var k = reach_lo(a.z, s.z); k < min((a.z + 1u) * s.z, n.z); k = k + 1u) {
        let wz = weight(k, a.z, s.z);
        for (var j = reach_lo(a.y, s.y); j < min((a.y + 1u) * s.y, n.y); j = j + 1u) {
            let wy = weight(j, a.y, s.y);
            for (var i = reach_lo(a.x, s.x); i < min((a.x + 1u) * s.x, n.x); i = i + 1u) {
                let wx = weight(i, a.x, s.x);
                let w = wx * wy * wz;
                if (w > 0.0) {
                    let v = 3u * voxel_index(i, j, k, n);
                    sum = sum + w * vec3<f32>(values[v], values[v + 1u], values[v + 2u]);
                }
            }
        }
    }
    let o = 3u * voxel_index(gid.x, gid.y, gid.z, d.xyz);
    out[o] = sum.x;
    out[o + 1u] = sum.y;
    out[o + 2u] = sum.z;
}
