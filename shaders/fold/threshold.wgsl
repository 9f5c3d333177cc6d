// threshold.wgsl: the parameters of the kernels that compare a value per voxel with a threshold
// (fold_stats, mark_at_most); prepended to them. A voxel is `held` where the held map is > 0
// (the fold repair never changes it: it moves with a bone).

// Keep in sync with abi::ThresholdParams.
struct ThresholdParams {
    dims: vec4<u32>,       // nx, ny, nz, unused
    chunks: vec4<u32>,     // voxels, voxels per chunk, chunks, unused
    threshold: f32,        // det J for the folds, mm for a distance
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

fn is_held(value: f32) -> bool {
    return value > 0.0;
}
