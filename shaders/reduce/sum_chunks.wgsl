// sum_chunks.wgsl: sums of (v - shift)^power (power 1 or 2; power 0 counts the values above
// the shift) over consecutive chunks of an f32 array, in f64, each in index order, so a reduction's partial sums are the same bits on the
// CPU twin and from run to run. The host adds the few partials (a chunk holds
// SumParams.counts.y values). Squares about the mean give a variance without cancellation.
//
// Bindings (group 0):
//   0 uniform  SumParams
//   1 storage  values: array<f32>
//   2 storage  sums: array<f64>   one per chunk (read_write)
// Dispatch: workgroups (ceil(chunks / 64), 1, 1).

// Keep in sync with abi::SumParams.
struct SumParams {
    counts: vec4<u32>,  // values, values per chunk, chunks, unused
    shift: f32,
    power: u32,         // 0 (a count), 1 or 2
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: SumParams;
@group(0) @binding(1) var<storage, read> values: array<f32>;
@group(0) @binding(2) var<storage, read_write> sums: array<f64>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    let n = params.counts;
    if (c >= n.z) {
        return;
    }
    var sum = 0.0lf;
    for (var v = c * n.y; v < min((c + 1u) * n.y, n.x); v = v + 1u) {
        let d = f64(values[v]) - f64(params.shift);
        var term = d;
        if (params.power == 2u) {
            term = d * d;
        } else if (params.power == 0u) {
            term = select(0.0lf, 1.0lf, d > 0.0lf);
        }
        sum = sum + term;
    }
    sums[c] = sum;
}
