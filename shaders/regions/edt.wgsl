// edt.wgsl: one axis of an exact Euclidean distance transform (Felzenszwalb & Huttenlocher's
// lower envelope of parabolas), for a stack of volumes at once: one invocation per line along
// the pass's axis. Three passes (x, y, z) give the distance (mm) from every voxel centre to the
// nearest voxel of a region, exact for grids with orthogonal axes (spacing per axis). The first
// pass starts volume s of the stack from the voxels whose input rounds (half up) to s + 1 —
// a label index map's voxels of index s + 1 (label_index), or where a smoothed 0/1 indicator is
// at least ½ — or its one volume from the voxels whose input rounds to 1 or more (the nearest
// of all the regions), with distance 0 there and none elsewhere; the last takes square roots.
//
// Bindings (group 0):
//   0 uniform  EdtParams
//   1 storage  input: array<f32>   one volume (first pass) or the stack, x fastest
//   2 storage  output: array<f32>  the stack: volumes one after another (read_write)
// Dispatch: workgroups (ceil(na/8), ceil(nb/8), volumes), a and b the two other axes.

// Keep in sync with abi::EdtParams.
struct EdtParams {
    dims: vec4<u32>,     // nx, ny, nz, unused
    spacing: vec4<f32>,  // mm between samples along x, y, z, unused
    axis: u32,           // the axis of this pass (0 x, 1 y, 2 z)
    volumes: u32,        // volumes in the stack
    start: u32,          // FROM_STACK, or a first pass (input is the index map): FROM_EACH_REGION, FROM_ANY_REGION
    last: u32,           // 1: last pass
}

@group(0) @binding(0) var<uniform> params: EdtParams;
@group(0) @binding(1) var<storage, read> input: array<f32>;
@group(0) @binding(2) var<storage, read_write> output: array<f32>;

// Where a pass starts from (abi::EDT_FROM_STACK, EDT_FROM_EACH_REGION; EDT_FROM_ANY_REGION is
// the other value).
const FROM_STACK: u32 = 0u;
const FROM_EACH_REGION: u32 = 1u;

// No sample along the line yet: the host's +infinity, which WGSL cannot write.
const FAR: f32 = 3.0e38;
// Longest line a pass takes (abi::MAX_EDT_LINE): the envelope lives in private arrays.
const MAX_LINE: u32 = 1024u;

var<private> hull: array<u32, MAX_LINE>;    // the envelope's parabolas (their sample index)
var<private> bounds: array<f32, MAX_LINE>;  // where each one starts to be the lowest

// Voxel (line position q) of the line gid, in the volume's flat index.
fn voxel_of(q: u32, gid: vec3<u32>) -> u32 {
    let d = params.dims.xyz;
    var c = vec3<u32>(0u);
    switch params.axis {
        case 0u: { c = vec3<u32>(q, gid.x, gid.y); }
        case 1u: { c = vec3<u32>(gid.x, q, gid.y); }
        default: { c = vec3<u32>(gid.x, gid.y, q); }
    }
    return voxel_index(c.x, c.y, c.z, d);
}

// The squared distance so far at line position q (FAR where none).
fn sample(q: u32, gid: vec3<u32>) -> f32 {
    let v = voxel_of(q, gid);
    let d = params.dims.xyz;
    if (params.start == FROM_STACK) {
        return input[gid.z * d.x * d.y * d.z + v];
    }
    let region = floor(input[v] + 0.5);
    var starts = region >= 1.0;  // FROM_ANY_REGION
    if (params.start == FROM_EACH_REGION) {
        starts = region == f32(gid.z + 1u);
    }
    return select(FAR, 0.0, starts);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    let axis = params.axis;
    let others = select(select(vec2<u32>(d.x, d.y), vec2<u32>(d.x, d.z), axis == 1u), vec2<u32>(d.y, d.z), axis == 0u);
    if (gid.x >= others.x || gid.y >= others.y || gid.z >= params.volumes) {
        return;
    }
    let n = d[axis];
    let h = params.spacing[axis];
    let base = gid.z * d.x * d.y * d.z;
    var count = 0u;
    for (var q = 0u; q < n; q = q + 1u) {
        let fq = sample(q, gid);
        if (fq >= FAR) {
            continue;
        }
        let xq = f32(q) * h;
        loop {
            if (count == 0u) {
                hull[0] = q;
                bounds[0] = -FAR;
                count = 1u;
                break;
            }
            let p = hull[count - 1u];
            let xp = f32(p) * h;
            let s = ((fq + xq * xq) - (sample(p, gid) + xp * xp)) / (2.0 * (xq - xp));
            if (s <= bounds[count - 1u]) {
                count = count - 1u;
            } else {
                hull[count] = q;
                bounds[count] = s;
                count = count + 1u;
                break;
            }
        }
    }
    var k = 0u;
    for (var q = 0u; q < n; q = q + 1u) {
        var out = FAR;
        if (count > 0u) {
            let xq = f32(q) * h;
            while (k + 1u < count && bounds[k + 1u] < xq) {
                k = k + 1u;
            }
            let e = xq - f32(hull[k]) * h;
            out = e * e + sample(hull[k], gid);
        }
        if (params.last == 1u) {
            out = sqrt(out);
        }
        output[base + voxel_of(q, gid)] = out;
    }
}
