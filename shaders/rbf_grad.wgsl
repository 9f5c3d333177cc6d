// rbf_grad.wgsl: one evaluation of the non-rigid stage's cost and its gradient field.
//
// The cubic-RBF warp R is known at the nodes of a coarse lattice (every `step`-th voxel of the
// target grid, evaluated on the host) and interpolated trilinearly at each voxel x. The moving
// image I0 (the source after the articulated initialisation, on the target grid) is sampled at
// x + R(x): W(x) = I0(x + R(x)). Output per voxel: W and the gradient of (W − T)² with respect
// to R(x), 2 (W − T) ∇I0(x + R(x)) in world mm. Points outside I0 give W = 0 and no gradient.
//
// Bindings (group 0):
//   0 uniform  RbfGradParams
//   1 storage  lattice: array<f32>  3 floats (R, mm) per lattice node, whole
//   2 storage  moving: array<f32>   I0 on the target grid, whole
//   3 storage  fixed: array<f32>    the target T, this slab
//   4 storage  out: array<f32>      4 floats per voxel of this slab (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(depth/4)).

@group(0) @binding(0) var<uniform> params: RbfGradParams;
@group(0) @binding(1) var<storage, read> lattice: array<f32>;
@group(0) @binding(2) var<storage, read> moving: array<f32>;
@group(0) @binding(3) var<storage, read> fixed: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;

fn sampled_value(index: u32) -> f32 {
    return moving[index];
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    let depth = params.slab.x;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= depth) {
        return;
    }
    let k = gid.z + d.w;
    let v = voxel_index(gid.x, gid.y, gid.z, vec3<u32>(d.x, d.y, depth));
    let s = warped_sample(gid.x, gid.y, k, fixed[v]);
    out[4u * v] = s.x;
    out[4u * v + 1u] = s.y;
    out[4u * v + 2u] = s.z;
    out[4u * v + 3u] = s.w;
}
