// geometry.wgsl: where a target voxel's displaced point lies in a source volume; prepended to
// the kernels that look a source up through a displacement field (resample, coverage,
// bone_at_source, fold_smooth). Mirrored in src/cpu/common.rs (source_index).
//
// Invariant: the target voxel index maps to the source index by index_to_source (3x4), and a
// displacement in mm by mm_to_source (3x3); both precomputed on the host in f64.

// Keep in sync with abi::ResampleParams.
struct ResampleParams {
    target_dims: vec4<u32>,      // nx, ny, nz, unused
    source_dims: vec4<u32>,      // nx, ny, nz, unused
    index_to_source: array<vec4<f32>, 3>,
    mm_to_source: array<vec4<f32>, 3>,
    background: f32,
    nearest: u32,                // 1: nearest neighbour (labels), 0: trilinear
    pad0: u32,
    pad1: u32,
}

// The continuous source index of target voxel p's point displaced by u (world mm).
fn source_index(g: ResampleParams, p: vec3<f32>, u: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        affine_row(g.index_to_source[0], p) + linear_row(g.mm_to_source[0], u),
        affine_row(g.index_to_source[1], p) + linear_row(g.mm_to_source[1], u),
        affine_row(g.index_to_source[2], p) + linear_row(g.mm_to_source[2], u),
    );
}
