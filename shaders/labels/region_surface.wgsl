// region_surface.wgsl: per voxel of a region map (a region's number per voxel, 0 for none),
// its number where one of its six neighbours inside the grid has another number, else 0: the
// boundary voxels of each region (where the adaptive stage pins a bone's surface), listed
// afterwards by list_flagged so the map itself need not come back.
//
// Bindings (group 0):
//   0 uniform  SurfaceParams
//   1 storage  regions: array<f32>  1 float per voxel
//   2 storage  surface: array<f32>  1 float per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::SurfaceParams.
struct SurfaceParams {
    dims: vec4<u32>,   // nx, ny, nz, unused
}

@group(0) @binding(0) var<uniform> params: SurfaceParams;
@group(0) @binding(1) var<storage, read> regions: array<f32>;
@group(0) @binding(2) var<storage, read_write> surface: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let region = regions[v];
    var boundary = false;
    let stride = vec3<u32>(1u, d.x, d.x * d.y);
    for (var a = 0u; a < 3u; a = a + 1u) {
        if (gid[a] > 0u && regions[v - stride[a]] != region) {
            boundary = true;
        }
        if (gid[a] + 1u < d[a] && regions[v + stride[a]] != region) {
            boundary = true;
        }
    }
    surface[v] = select(0.0, region, boundary && region > 0.0);
}
