// list_flagged.wgsl: the flagged values (> 0) of an f32 array and their indices, in index
// order. Each chunk of ListParams.counts.y values (sum_chunks' chunks, whose sums of the 0/1
// flags count them) writes its flagged values from its offset: the flagged values of the chunks
// before it, an exclusive prefix sum of those counts made by the host. So the list is the same
// on both backends and from run to run, whatever order the threads run in, and only the list
// and one count per chunk cross to the host, not the array.
//
// Bindings (group 0):
//   0 uniform  ListParams
//   1 storage  flags: array<f32>     listed where > 0
//   2 storage  offsets: array<u32>   one per chunk
//   3 storage  indices: array<u32>   one per flagged value (read_write)
//   4 storage  values: array<f32>    the flagged values (read_write)
// Dispatch: workgroups (ceil(chunks / 64), 1, 1).

// Keep in sync with abi::ListParams.
struct ListParams {
    counts: vec4<u32>,  // values, values per chunk, chunks, unused
}

@group(0) @binding(0) var<uniform> params: ListParams;
@group(0) @binding(1) var<storage, read> flags: array<f32>;
@group(0) @binding(2) var<storage, read> offsets: array<u32>;
@group(0) @binding(3) var<storage, read_write> indices: array<u32>;
@group(0) @binding(4) var<storage, read_write> values: array<f32>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    let n = params.counts;
    if (c >= n.z) {
        return;
    }
    var at = offsets[c];
    for (var v = c * n.y; v < min((c + 1u) * n.y, n.x); v = v + 1u) {
        let flag = flags[v];
        if (flag > 0.0) {
            indices[at] = v;
            values[at] = flag;
            at = at + 1u;
        }
    }
}
