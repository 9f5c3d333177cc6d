// lncc.wgsl: the local correlation of two images from their box sums (local_moments.wgsl),
// summed per chunk of consecutive voxels in index order, so that the CPU twin gives the same
// bits: per voxel, ρ² = cab² / (va vb) of its window (window.wgsl; cut at the grid's faces),
// in [0, 1]. A window where either image is flat has no correlation: it adds 0 and is not
// counted. The host adds the chunks' sums.
//
// Bindings (group 0):
//   0 uniform  LnccParams
//   1 storage  sums: array<f32>   5 floats per voxel (local_moments.wgsl)
//   2 storage  out: array<f32>    2 floats per chunk: Σ ρ², voxels counted (read_write)
// Dispatch: workgroups (ceil(chunks / 64), 1, 1).

// Keep in sync with abi::LnccParams.
struct LnccParams {
    dims: vec4<u32>,     // nx, ny, nz, unused
    chunks: vec4<u32>,   // voxels, voxels per chunk, chunks, unused
    radius: u32,         // the window's radius (voxels)
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: LnccParams;
@group(0) @binding(1) var<storage, read> sums: array<f32>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;

// ρ² at voxel v (index i, j, k), or -1 where a window is flat.
fn squared_correlation(v: u32, i: u32, j: u32, k: u32) -> f32 {
    let s = array<f32, 5>(sums[5u * v], sums[5u * v + 1u], sums[5u * v + 2u],
                          sums[5u * v + 3u], sums[5u * v + 4u]);
    let w = window_at(s, vec4<u32>(params.dims.xyz, params.radius), i, j, k);
    if (w.flat) {
        return -1.0;
    }
    return min(w.cab * w.cab / (w.va * w.vb), 1.0);
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let c = gid.x;
    let n = params.chunks;
    if (c >= n.z) {
        return;
    }
    let d = params.dims;
    var total = 0.0;
    var counted = 0.0;
    for (var v = c * n.y; v < min((c + 1u) * n.y, n.x); v = v + 1u) {
        let rho2 = squared_correlation(v, v % d.x, (v / d.x) % d.y, v / (d.x * d.y));
        if (rho2 >= 0.0) {
            total = total + rho2;
            counted = counted + 1.0;
        }
    }
    out[2u * c] = total;
    out[2u * c + 1u] = counted;
}
