// warp_field.wgsl: the non-rigid warp R at every voxel, interpolated from the lattice exactly as
// rbf_grad and warp_cost interpolate it during optimisation (lattice_warp.wgsl), so the field
// written out is the warp that was optimised.
//
// Bindings (group 0):
//   0 uniform  RbfGradParams
//   1 storage  lattice: array<f32>  3 floats (R, mm) per lattice node, whole
//   2 storage  out: array<f32>      3 floats per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

@group(0) @binding(0) var<uniform> params: RbfGradParams;
@group(0) @binding(1) var<storage, read> lattice: array<f32>;
@group(0) @binding(2) var<storage, read_write> out: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let r = warp_at(gid.x, gid.y, gid.z);
    let o = 3u * voxel_index(gid.x, gid.y, gid.z, d.xyz);
    out[o] = r.x;
    out[o + 1u] = r.y;
    out[o + 2u] = r.z;
}
