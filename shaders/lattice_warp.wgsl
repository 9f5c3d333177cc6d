// lattice_warp.wgsl: the non-rigid warp R interpolated from a coarse lattice; prepended to the
// kernels that read it (warp_field, warp_image, warp_cost), which declare `params: RbfGradParams` and
// `lattice` (3 floats per node). Mirrored in src/cpu/lattice_warp.rs (LatticeTaps::row for column,
// RowTaps::warp_at).

// Keep in sync with abi::RbfGradParams.
struct RbfGradParams {
    dims: vec4<u32>,          // nx, ny, nz, unused
    lattice_dims: vec4<u32>,  // lx, ly, lz, unused
    lattice_step: vec4<u32>,  // step along x, y, z (voxels), unused
    moving_dims: vec4<u32>,   // the moving image's nx, ny, nz, unused
    stride: vec4<u32>,        // target voxel (i, j, k) lies on moving voxel stride * (i, j, k)
    mm_to_index: array<vec4<f32>, 3>,
    gradient_to_world: array<vec4<f32>, 3>,
}

fn node(i: u32, j: u32, k: u32) -> vec3<f32> {
    let n = 3u * voxel_index(i, j, k, params.lattice_dims.xyz);
    return vec3<f32>(lattice[n], lattice[n + 1u], lattice[n + 2u]);
}

// The lattice column at node x blended along y, then z, at weights t (the part of the
// trilinear interpolation a whole voxel row shares: the CPU twin blends it once per row).
fn column(x: u32, i0: vec3<u32>, i1: vec3<u32>, t: vec3<f32>) -> vec3<f32> {
    let c0 = (1.0 - t.y) * node(x, i0.y, i0.z) + t.y * node(x, i1.y, i0.z);
    let c1 = (1.0 - t.y) * node(x, i0.y, i1.z) + t.y * node(x, i1.y, i1.z);
    return (1.0 - t.z) * c0 + t.z * c1;
}

// Trilinear interpolation of the lattice at voxel (i, j, k): the columns at the two x nodes
// around it, then x.
fn warp_at(i: u32, j: u32, k: u32) -> vec3<f32> {
    let s = params.lattice_step.xyz;
    let top = params.lattice_dims.xyz - vec3<u32>(1u);
    let c = vec3<u32>(i, j, k);
    let i0 = min(c / s, top);
    let i1 = min(i0 + vec3<u32>(1u), top);
    let t = vec3<f32>(c - i0 * s) / vec3<f32>(s);
    return (1.0 - t.x) * column(i0.x, i0, i1, t) + t.x * column(i1.x, i0, i1, t);
}
