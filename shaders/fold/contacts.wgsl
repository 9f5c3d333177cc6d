// contacts.wgsl: whether a voxel's difference stencil spans two bones (fold_stats.wgsl's
// header says why those voxels are counted apart); prepended (after threshold.wgsl or the
// push's parameters) to the kernels that bind the held map as `held` and whose `params` have
// the grid's `dims`. Mirrored in src/cpu/fold/contacts.rs. A voxel is held where the map is
// > 0, as threshold.wgsl's is_held says (not every kernel that prepends this has that file).

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

// How voxel v's stencil meets the bones: x whether along one axis its two neighbours are held
// in two different bones, y whether all six are held, in two different bones.
fn bone_spans(v: u32) -> vec2<bool> {
    let d = params.dims.xyz;
    let c = vec3<u32>(v % d.x, (v / d.x) % d.y, v / (d.x * d.y));
    let first = held[face_neighbour(c, 0u, -1)];
    var all_held = true;
    var two_bones = false;
    var spans_along_an_axis = false;
    for (var axis = 0u; axis < 3u; axis = axis + 1u) {
        let lo = held[face_neighbour(c, axis, -1)];
        let hi = held[face_neighbour(c, axis, 1)];
        let both_held = lo > 0.0 && hi > 0.0;
        all_held = all_held && both_held;
        two_bones = two_bones || lo != first || hi != first;
        spans_along_an_axis = spans_along_an_axis || (both_held && lo != hi);
    }
    return vec2<bool>(spans_along_an_axis, all_held && two_bones);
}

// Whether voxel v is a bone contact: its stencil spans two bones either way.
fn is_contact(v: u32) -> bool {
    let spans = bone_spans(v);
    return spans.x || spans.y;
}
