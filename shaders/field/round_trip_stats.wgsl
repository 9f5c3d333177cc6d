// round_trip_stats.wgsl: how closely an inverse undoes its field (images/inverse.rs), per chunk
// of consecutive source voxels inside the body (source value > 0), each chunk in index order so
// the results are the same bits on the CPU twin: the sum and the largest of the round-trip
// residuals (mm) of the voxels with a preimage, their count, the count of those farther than
// the `far` distance, and the count without a preimage (residual < 0). The host adds the
// chunks; only they come back, not the residual volume.
//
// Bindings (group 0):
//   0 uniform  RoundTripParams
//   1 storage  residual: array<f32>  1 float per source voxel (mm; < 0: no preimage)
//   2 storage  source: array<f32>    the source image, 1 float per voxel
//   3 storage  stats: array<f64>     ROUND_TRIP_WIDTH per chunk (read_write)
// Dispatch: workgroups (ceil(chunks / 64), 1, 1).

// Keep in sync with abi::RoundTripParams.
struct RoundTripParams {
    counts: vec4<u32>,  // voxels, voxels per chunk, chunks, unused
    far: f32,           // mm
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: RoundTripParams;
@group(0) @binding(1) var<storage, read> residual: array<f32>;
@group(0) @binding(2) var<storage, read> source: array<f32>;
@group(0) @binding(3) var<storage, read_write> stats: array<f64>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    let n = params.counts;
    if (c >= n.z) {
        return;
    }
    var sum = 0.0lf;
    var largest = 0.0lf;
    var counted = 0.0lf;
    var far = 0.0lf;
    var without = 0.0lf;
    for (var v = c * n.y; v < min((c + 1u) * n.y, n.x); v = v + 1u) {
        if (source[v] <= 0.0) {
            continue;
        }
        let r = residual[v];
        if (r < 0.0) {
            without = without + 1.0lf;
            continue;
        }
        sum = sum + f64(r);
        largest = max(largest, f64(r));
        counted = counted + 1.0lf;
        far = far + select(0.0lf, 1.0lf, r > params.far);
    }
    stats[5u * c] = sum;
    stats[5u * c + 1u] = largest;
    stats[5u * c + 2u] = counted;
    stats[5u * c + 3u] = far;
    stats[5u * c + 4u] = without;
}
