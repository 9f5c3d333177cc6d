// push_list.wgsl: the fold push's lists of voxels to lift and the state of its sweeps, kept
// on the device so that only the state comes back, every few sweeps (src/images/unfold.rs).
// A list holds each colour's voxels (i mod 3 + 3 (j mod 3) + 9 (k mod 3)) in a bucket of its
// own, as long as the grid has voxels of that colour, so appending never overflows. Prepended
// to the push's kernels whose `params` have the grid's `dims`. Mirrored in
// src/cpu/fold/push_list.rs; the state's layout is abi::push_state's.

// The state: one u32 each, then the counts. The workgroup counts of a sweep's dispatches are
// a buffer of their own (fold_advance.wgsl writes them), as a buffer a dispatch reads them
// from cannot be one it writes.
const STATE_SWEEP: u32 = 0u;           // the sweep under way, from 1 (0 before the first)
const STATE_STOPPED: u32 = 1u;         // 1 once the pass has ended
const STATE_CONTACTS_ALONE: u32 = 2u;  // sweeps in a row that left only bone contacts
const STATE_LIFTED: u32 = 3u;          // voxels of the next list that are not bone contacts
const STATE_CURRENT: u32 = 4u;         // 27 counts: this sweep's list, by colour
const STATE_NEXT: u32 = 31u;           // 27 counts: the next sweep's list, by colour
const COLOURS: u32 = 27u;
const GROUP: u32 = 64u;                // invocations per workgroup of the list kernels
const ROW_GROUPS: u32 = 32768u;        // workgroups per row of a list dispatch

// The colour of voxel p: two voxels of one colour lie at least three steps apart.
fn colour_of(p: vec3<u32>) -> u32 {
    return p.x % 3u + 3u * (p.y % 3u) + 9u * (p.z % 3u);
}

// Voxels of colour c in a grid of `dims`.
fn colour_size(c: u32, dims: vec3<u32>) -> u32 {
    let residue = vec3<u32>(c % 3u, (c / 3u) % 3u, c / 9u);
    let n = (dims + vec3<u32>(2u) - residue) / vec3<u32>(3u);
    return n.x * n.y * n.z;
}

// Where colour c's bucket starts in a list.
fn bucket_start(c: u32, dims: vec3<u32>) -> u32 {
    var start = 0u;
    for (var b = 0u; b < c; b = b + 1u) {
        start = start + colour_size(b, dims);
    }
    return start;
}

// The list entry invocation `gid` of a list dispatch handles (rows of ROW_GROUPS workgroups,
// so that a long list stays within the per-dimension limit).
fn entry_of(gid: vec3<u32>) -> u32 {
    return gid.x + gid.y * ROW_GROUPS * GROUP;
}
