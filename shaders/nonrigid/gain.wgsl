// gain.wgsl: the parameters of the gain kernels (gain_terms, gain_ratio, gain_apply).

// Keep in sync with abi::GainParams.
struct GainParams {
    dims: vec4<u32>,               // nx, ny, nz of the grid written, voxels
    coarse_dims: vec4<u32>,        // nx, ny, nz of the smoothed grid, unused
    to_coarse: array<vec4<f32>, 3>, // voxel index of the grid written -> smoothed grid index
    limits: vec4<f32>,             // energy floor, most gain, unused x2
}
