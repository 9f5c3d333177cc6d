// sum_partials.wgsl: adds per-chunk partial results (f64) in chunk order: out[v] =
// Σ_c partials[c · values + v]. It finishes rbf_adjoint's chunked sums on the device, so only
// the totals are read back.
//
// Bindings (group 0):
//   0 uniform  PartialsParams
//   1 storage  partials: array<f64>  chunks × values
//   2 storage  out: array<f64>       values (read_write)
// Dispatch: workgroups (ceil(values / 64), 1, 1).

// Keep in sync with abi::PartialsParams.
struct PartialsParams {
    counts: vec4<u32>,  // values per chunk, chunks, unused x2
}

@group(0) @binding(0) var<uniform> params: PartialsParams;
@group(0) @binding(1) var<storage, read> partials: array<f64>;
@group(0) @binding(2) var<storage, read_write> out: array<f64>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let v = gid.x;
    let values = params.counts.x;
    if (v >= values) {
        return;
    }
    var sum = 0.0lf;
    for (var c = 0u; c < params.counts.y; c = c + 1u) {
        sum = sum + partials[c * values + v];
    }
    out[v] = sum;
}
