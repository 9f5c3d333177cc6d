// sum_partials.wgsl: adds per-chunk partial results in chunk order, a group of chunks at a
// time, in f64: out[g · values + v] = Σ_{c in group g} partials[c · values + v]. It finishes
// chunked sums on the device (rbf_adjoint's per chunk of nodes, rigid_gn's and rigid_score's
// per column), so only the totals are read back. The host runs it again on its own output
// until one group is left (abi::PartialsParams::passes), which keeps every invocation's loop
// short (lavapipe ends loops after 65 535 iterations).
//
// `Partial` is f32 or f64: the kernel is assembled twice, after a one-line alias.
//
// Bindings (group 0):
//   0 uniform  PartialsParams
//   1 storage  partials: array<Partial>  chunks × values
//   2 storage  out: array<f64>           groups × values (read_write)
// Dispatch: workgroups (ceil(values / 64), groups, 1).

// Keep in sync with abi::PartialsParams.
struct PartialsParams {
    counts: vec4<u32>,  // values per chunk, chunks, chunks per group, unused
}

@group(0) @binding(0) var<uniform> params: PartialsParams;
@group(0) @binding(1) var<storage, read> partials: array<Partial>;
@group(0) @binding(2) var<storage, read_write> out: array<f64>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let v = gid.x;
    let g = gid.y;
    let values = params.counts.x;
    if (v >= values) {
        return;
    }
    let first = g * params.counts.z;
    let last = min(first + params.counts.z, params.counts.y);
    var sum = 0.0lf;
    for (var c = first; c < last; c = c + 1u) {
        sum = sum + f64(partials[c * values + v]);
    }
    out[g * values + v] = sum;
}
