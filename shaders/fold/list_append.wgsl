// list_append.wgsl: appending a voxel to the next list of the fold push (push_list.wgsl has
// the layout); prepended after it to the kernels that bind the list as `next` and the state
// as `state` (atomic). Mirrored in src/cpu/fold/push_list.rs (Appender::append). The order
// within a bucket depends on which invocation comes first; the pushes of one colour do not
// depend on their order (fold_push.wgsl), so the result does not either.

// Appends voxel v, at p in the grid, with lift code `code` (lift_rule.wgsl: 2 a bone contact).
fn append(v: u32, p: vec3<u32>, code: f32) {
    let c = colour_of(p);
    let slot = atomicAdd(&state[STATE_NEXT + c], 1u);
    next[bucket_start(c, params.dims.xyz) + slot] = v;
    if (code == 1.0) {
        atomicAdd(&state[STATE_LIFTED], 1u);
    }
}
