// resample.wgsl: warped(x) = source(x + u(x)) for every voxel x of the target grid, trilinear
// (or nearest neighbour for label maps),
// `background` outside the source. u is a displacement in world mm (RAS) on the target grid.
//
// Bindings (group 0):
//   0 uniform  ResampleParams
//   1 storage  source: array<f32>   whole source volume, x fastest
//   2 storage  field:  array<f32>   3 floats per target voxel (packed, 12 B)
//   3 storage  warped: array<f32>   1 float per target voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)); one invocation per target voxel.

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
    let nz = params.target_dims.z;
    if (gid.x >= nx || gid.y >= ny || gid.z >= nz) {
        return;
    }
    let local = voxel_index(gid.x, gid.y, gid.z, vec3<u32>(nx, ny, nz));
    let p = vec3<f32>(f32(gid.x), f32(gid.y), f32(gid.z));
    let u = vec3<f32>(field[3u * local], field[3u * local + 1u], field[3u * local + 2u]);
    let q = source_index(params, p, u);
    if (params.nearest == 1u) {
        warped[local] = nearest(q, params.source_dims.xyz, params.background);
    } else {
        warped[local] = trilinear(q, params.source_dims.xyz, params.background);
    }
}
