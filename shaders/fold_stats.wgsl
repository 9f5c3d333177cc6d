// fold_stats.wgsl: a Jacobian determinant's fold statistics per chunk of consecutive voxels,
// each chunk in index order so the results are the same bits on the CPU twin: the minimum,
// the voxels with det <= 0 (folded), with det <= threshold, and with det <= threshold that
// are not held. The host combines the chunks (min of minima, sums of counts, exact in f32
// for a chunk's 1024 voxels).
//
// Bindings (group 0):
//   0 uniform  ThresholdParams (threshold.wgsl)
//   1 storage  det: array<f32>    1 float per voxel
//   2 storage  held: array<f32>   1 float per voxel (> 0: held)
//   3 storage  stats: array<f32>  4 floats per chunk (read_write)
// Dispatch: workgroups (ceil(chunks / 64), 1, 1).

@group(0) @binding(0) var<uniform> params: ThresholdParams;
@group(0) @binding(1) var<storage, read> det: array<f32>;
@group(0) @binding(2) var<storage, read> held: array<f32>;
@group(0) @binding(3) var<storage, read_write> stats: array<f32>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    let n = params.chunks;
    if (c >= n.z) {
        return;
    }
    let threshold = params.threshold.x;
    var lowest = 3.4e38;
    var folded = 0.0;
    var low = 0.0;
    var low_free = 0.0;
    for (var v = c * n.y; v < min((c + 1u) * n.y, n.x); v = v + 1u) {
        let d = det[v];
        lowest = min(lowest, d);
        folded = folded + select(0.0, 1.0, d <= 0.0);
        low = low + select(0.0, 1.0, d <= threshold);
        low_free = low_free + select(0.0, 1.0, d <= threshold && !is_held(held[v]));
    }
    stats[4u * c] = lowest;
    stats[4u * c + 1u] = folded;
    stats[4u * c + 2u] = low;
    stats[4u * c + 3u] = low_free;
}
