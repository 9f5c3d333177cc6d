// fold_stats.wgsl: a Jacobian determinant's fold statistics per chunk of consecutive voxels,
// each chunk in index order so the results are the same bits on the CPU twin. Voxels at or
// below the threshold at a bone contact (below) apart: the minimum, the voxels with det <= 0
// (folded), with det <= threshold, and with det <= threshold that are not held; then the
// contacts with det <= 0. The host combines the chunks (min of minima, sums of counts, exact
// in f32 for a chunk's 1024 voxels).
//
// A bone contact is a voxel whose six stencil neighbours (the voxels its central differences
// take; the voxel itself on a face) are all held, in two different bones (held values are bone
// numbers). Its determinant is then a function of the bones' rigid motions alone: where bones
// slide on each other at a joint the field jumps from one bone's motion to the other's, the
// difference across the jump measures the slide, not a fold, and nothing that keeps bones rigid
// can change it. The independent generator's true field at 90 degrees has det <= 0 there too.
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

// The voxel one step from voxel c along `axis` (0..2) in direction `step` (-1 or 1), the
// voxel itself at the volume's faces.
fn face_neighbour(c: vec3<u32>, axis: u32, step: i32) -> u32 {
    let d = params.dims.xyz;
    var p = c;
    if (step < 0 && p[axis] > 0u) {
        p[axis] = p[axis] - 1u;
    }
    if (step > 0 && p[axis] + 1u < d[axis]) {
        p[axis] = p[axis] + 1u;
    }
    return voxel_index(p.x, p.y, p.z, d);
}

// Whether voxel v is a bone contact (the header's).
fn is_contact(v: u32) -> bool {
    let d = params.dims.xyz;
    let c = vec3<u32>(v % d.x, (v / d.x) % d.y, v / (d.x * d.y));
    let first = held[face_neighbour(c, 0u, -1)];
    var all_held = true;
    var two_bones = false;
    for (var s = 0u; s < 6u; s = s + 1u) {
        let other = held[face_neighbour(c, s / 2u, 2 * i32(s % 2u) - 1)];
        all_held = all_held && is_held(other);
        two_bones = two_bones || other != first;
    }
    return all_held && two_bones;
}

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
