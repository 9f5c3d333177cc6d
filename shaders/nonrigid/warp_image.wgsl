// warp_image.wgsl: the moving image seen through the non-rigid stage's warp, W(x) = I0(x + R(x)),
// at every voxel x of the target grid; 0 where x + R(x) falls outside I0. The host loop measures
// the fit per cell and the intensity gain on it.
//
// R is known at the nodes of a coarse lattice (every `step`-th voxel along each axis,
// rbf_lattice) and interpolated trilinearly (lattice_warp.wgsl), as the cost's kernels do.
//
// Bindings (group 0):
//   0 uniform  RbfGradParams
//   1 storage  lattice: array<f32>  3 floats (R, mm) per lattice node
//   2 storage  moving: array<f32>   I0 on the target grid
//   3 storage  warped: array<f32>   W, one per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

@group(0) @binding(0) var<uniform> params: RbfGradParams;
@group(0) @binding(1) var<storage, read> lattice: array<f32>;
@group(0) @binding(2) var<storage, read> moving: array<f32>;
@group(0) @binding(3) var<storage, read_write> warped: array<f32>;

fn sampled_value(index: u32) -> f32 {
    return moving[index];
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d.xyz);
    warped[v] = warped_sample(gid.x, gid.y, gid.z, 0.0).x;
}
