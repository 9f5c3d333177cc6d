// fold_stats.wgsl: a Jacobian determinant's fold statistics per chunk of consecutive voxels,
// each chunk in index order so the results are the same bits on the CPU twin. Voxels at or
// below the threshold at a bone contact (below) apart: the minimum, the voxels with det <= 0
// (folded), with det <= threshold, and with det <= threshold that are not held; then the
// contacts with det <= 0. The host combines the chunks (min of minima, sums of counts, exact
// in f32 for a chunk's 1024 voxels).
//
// A bone contact (contacts.wgsl) is a voxel whose stencil (the voxels its central
// differences take; the voxel itself on a face) spans two bones held rigid (held values are
// bone numbers): either along one axis its two neighbours are held in two different bones, or
// all six neighbours are held, in two different bones. Where bones slide on each other at a joint the field jumps from one
// bone's rigid motion to the other's; a difference across that jump measures the slide between
// the two motions, not the field's derivative, and nothing that keeps bones rigid can change
// it. The independent generator's own true field at 90 degrees (1 mm knee) has det <= 0 at
// 43 of its 108 body voxels whose stencil spans two bones along an axis.
//
// Bindings (group 0):
//   0 uniform  ThresholdParams (threshold.wgsl)
//   1 storage  det: array<f32>    1 float per voxel
//   2 storage  held: array<f32>   1 float per voxel (> 0: held)
//   3 storage  stats: array<f32>  5 floats per chunk (read_write)
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
    let threshold = params.threshold;
    var lowest = 3.4e38;
    var folded = 0.0;
    var low = 0.0;
    var low_free = 0.0;
    var contacts = 0.0;
    for (var v = c * n.y; v < min((c + 1u) * n.y, n.x); v = v + 1u) {
        let d = det[v];
        // Only a voxel at or below the threshold is looked at for a contact (the test reads
        // seven voxels; most voxels are far above it).
        if (d <= threshold && is_contact(v)) {
            contacts = contacts + select(0.0, 1.0, d <= 0.0);
            continue;
        }
        lowest = min(lowest, d);
        folded = folded + select(0.0, 1.0, d <= 0.0);
        low = low + select(0.0, 1.0, d <= threshold);
        low_free = low_free + select(0.0, 1.0, d <= threshold && !is_held(held[v]));
    }
    stats[5u * c] = lowest;
    stats[5u * c + 1u] = folded;
    stats[5u * c + 2u] = low;
    stats[5u * c + 3u] = low_free;
    stats[5u * c + 4u] = contacts;
}
