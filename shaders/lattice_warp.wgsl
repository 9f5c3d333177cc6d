// lattice_warp.wgsl: the non-rigid warp R interpolated from a coarse lattice; prepended to the
// kernels that read it (warp_field, warp_image, warp_cost), which declare `params: RbfGradParams` and
// `lattice` (3 floats per node). Mirrored in src/cpu/warp_image.rs (warp_at).

// Keep in sync with abi::RbfGradParams.
struct RbfGradParams {
    dims: vec4<u32>,          // nx, ny, nz, unused
    lattice_dims: vec4<u32>,  // lx, ly, lz, unused
    lattice_step: vec4<u32>,  // step along x, y, z (voxels), unused
    mm_to_index: array<vec4<f32>, 3>,
    gradient_to_world: array<vec4<f32>, 3>,
}

fn node(i: u32, j: u32, k: u32) -> vec3<f32> {
    let n = 3u * voxel_index(i, j, k, params.lattice_dims.xyz);
    return vec3<f32>(lattice[n], lattice[n + 1u], lattice[n + 2u]);
}

// Trilinear interpolation of the lattice at voxel (i, j, k).
fn warp_at(i: u32, j: u32, k: u32) -> vec3<f32> {
    let s = params.lattice_step.xyz;
    let top = params.lattice_dims.xyz - vec3<u32>(1u);
    let c = vec3<u32>(i, j, k);
    let i0 = min(c / s, top);
    let i1 = min(i0 + vec3<u32>(1u), top);
    let t = vec3<f32>(c - i0 * s) / vec3<f32>(s);
    let c00 = (1.0 - t.x) * node(i0.x, i0.y, i0.z) + t.x * node(i1.x, i0.y, i0.z);
    let c10 = (1.0 - t.x) * node(i0.x, i1.y, i0.z) + t.x * node(i1.x, i1.y, i0.z);
    let c01 = (1.0 - t.x) * node(i0.x, i0.y, i1.z) + t.x * node(i1.x, i0.y, i1.z);
    let c11 = (1.0 - t.x) * node(i0.x, i1.y, i1.z) + t.x * node(i1.x, i1.y, i1.z);
    let c0 = (1.0 - t.y) * c00 + t.y * c10;
    let c1 = (1.0 - t.y) * c01 + t.y * c11;
    return (1.0 - t.z) * c0 + t.z * c1;
}
