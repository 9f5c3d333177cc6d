// gain.wgsl: the parameters of the gain kernels (gain_terms, gain_ratio, gain_apply).

// Keep in sync with abi::GainParams.
struct GainParams {
    dims: vec4<u32>,               // nx, ny, nz of the grid written, unused
    coarse_dims: vec4<u32>,        // nx, ny, nz of the smoothed grid, unused
    to_coarse: array<vec4<f32>, 3>, // voxel index of the grid written -> smoothed grid index
    floor: f32,                    // smoothed energy at or below which the gain is 1
    most: f32,                     // most gain
    pad0: u32,
    pad1: u32,
}
