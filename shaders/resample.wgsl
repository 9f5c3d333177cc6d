// resample.wgsl: warped(x) = source(x + u(x)) for every voxel x of the target grid, trilinear
// (or nearest neighbour for label maps),
// `background` outside the source. u is a displacement in world mm (RAS) on the target grid.
//
// Bindings (group 0):
//   0 uniform  ResampleParams
//   1 storage  source: array<f32>   whole source volume, x fastest
//   2 storage  field:  array<f32>   3 floats per voxel (packed, 12 B) for this slab only
//   3 storage  warped: array<f32>   1 float per voxel, this slab only (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(depth/4)); one invocation per voxel of a
//   slab of `depth` slices starting at slice z0. The host splits the target into slabs so no
//   binding exceeds the device limit and no dimension exceeds 65535 workgroups.
// Invariant: the target voxel index maps to the source index by index_to_source (3x4), and a
//   displacement in mm by mm_to_source (3x3); both precomputed on the host in f64.

// Keep in sync with abi::ResampleParams.
struct ResampleParams {
    target_dims: vec4<u32>,      // nx, ny, nz, z0 (first slice of this slab)
    source_dims: vec4<u32>,      // nx, ny, nz, depth (slices in this slab)
    index_to_source: array<vec4<f32>, 3>,
    mm_to_source: array<vec4<f32>, 3>,
    background: f32,
    nearest: u32,                // 1: nearest neighbour (labels), 0: trilinear
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: ResampleParams;
@group(0) @binding(1) var<storage, read> source: array<f32>;
@group(0) @binding(2) var<storage, read> field: array<f32>;
@group(0) @binding(3) var<storage, read_write> warped: array<f32>;

fn sampled_value(index: u32) -> f32 {
    return source[index];
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let nx = params.target_dims.x;
    let ny = params.target_dims.y;
    let depth = params.source_dims.w;
    if (gid.x >= nx || gid.y >= ny || gid.z >= depth) {
        return;
    }
    let local = voxel_index(gid.x, gid.y, gid.z, vec3<u32>(nx, ny, depth));
    let p = vec3<f32>(f32(gid.x), f32(gid.y), f32(gid.z + params.target_dims.w));
    let u = vec3<f32>(field[3u * local], field[3u * local + 1u], field[3u * local + 2u]);
    let q = vec3<f32>(
        affine_row(params.index_to_source[0], p) + linear_row(params.mm_to_source[0], u),
        affine_row(params.index_to_source[1], p) + linear_row(params.mm_to_source[1], u),
        affine_row(params.index_to_source[2], p) + linear_row(params.mm_to_source[2], u),
    );
    if (params.nearest == 1u) {
        warped[local] = nearest(q, params.source_dims.xyz, params.background);
    } else {
        warped[local] = trilinear(q, params.source_dims.xyz, params.background);
    }
}
