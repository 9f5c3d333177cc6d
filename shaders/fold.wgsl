// fold.wgsl: the parameters of the fold kernels (fold_stats, fold_mark); prepended to them.
// A voxel is `held` where the held map is > 0 (it moves with a bone and is never changed).

// Keep in sync with abi::FoldParams.
struct FoldParams {
    dims: vec4<u32>,       // nx, ny, nz, unused
    chunks: vec4<u32>,     // voxels, voxels per chunk, chunks, unused
    threshold: vec4<f32>,  // det J at or below which a voxel counts as folded, unused x3
}

fn is_held(value: f32) -> bool {
    return value > 0.0;
}
