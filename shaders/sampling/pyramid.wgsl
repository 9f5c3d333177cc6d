// pyramid.wgsl: one level down a Gaussian pyramid. Along each axis with factor 2 the output
// voxel i sits between input voxels 2i and 2i+1 and is the binomial average
// (1, 3, 3, 1) / 8 of input voxels 2i-1 .. 2i+2 (a Gaussian of σ ≈ 0.87 input voxels, the
// smoothing that 2× decimation needs); along an axis with factor 1 (already much coarser than
// the others: not halved) the voxel is copied. Indices beyond the volume are clamped to it.
//
// Bindings (group 0):
//   0 uniform  PyramidParams
//   1 storage  input: array<f32>   the finer level, whole
//   2 storage  output: array<f32>  the coarser level (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)) over the coarser level.

// Keep in sync with abi::PyramidParams.
struct PyramidParams {
    dims: vec4<u32>,        // output nx, ny, nz, unused
    input_dims: vec4<u32>,  // input nx, ny, nz, unused
    factors: vec4<u32>,     // 1 or 2 per axis, unused
}

@group(0) @binding(0) var<uniform> params: PyramidParams;
@group(0) @binding(1) var<storage, read> input: array<f32>;
@group(0) @binding(2) var<storage, read_write> output: array<f32>;

// Input index and weight of tap t (0..3) along an axis for output index o.
fn tap(o: u32, t: u32, factor: u32, n: u32) -> vec2<f32> {
    if (factor == 1u) {
        return vec2<f32>(f32(o), select(0.0, 1.0, t == 0u));
    }
    let i = clamp(i32(2u * o + t) - 1, 0, i32(n) - 1);
    let w = select(1.0, 3.0, t == 1u || t == 2u) / 8.0;
    return vec2<f32>(f32(i), w);
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let k = gid.z;
    let n = params.input_dims.xyz;
    var sum = 0.0;
    for (var tz = 0u; tz < 4u; tz = tz + 1u) {
        let z = tap(k, tz, params.factors.z, n.z);
        for (var ty = 0u; ty < 4u; ty = ty + 1u) {
            let y = tap(gid.y, ty, params.factors.y, n.y);
            for (var tx = 0u; tx < 4u; tx = tx + 1u) {
                let x = tap(gid.x, tx, params.factors.x, n.x);
                let w = x.y * y.y * z.y;
                if (w > 0.0) {
                    sum = sum + w * input[voxel_index(u32(x.x), u32(y.x), u32(z.x), n)];
                }
            }
        }
    }
    output[voxel_index(gid.x, gid.y, gid.z, d.xyz)] = sum;
}
