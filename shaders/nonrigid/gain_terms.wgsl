// gain_terms.wgsl: the two images the intensity gain is the smoothed ratio of (crate::gain):
// product = W · T and energy = W · W per voxel, W the moving image through the warp found so
// far (warp_image) and T the target.
//
// Bindings (group 0):
//   0 uniform  GainParams (voxels)
//   1 storage  warped: array<f32>
//   2 storage  target_image: array<f32>
//   3 storage  product: array<f32>  (read_write)
//   4 storage  energy: array<f32>   (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)): a 1-D dispatch of a paper-sized
// grid would exceed 65535 workgroups.

@group(0) @binding(0) var<uniform> params: GainParams;
@group(0) @binding(1) var<storage, read> warped: array<f32>;
@group(0) @binding(2) var<storage, read> target_image: array<f32>;
@group(0) @binding(3) var<storage, read_write> product: array<f32>;
@group(0) @binding(4) var<storage, read_write> energy: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let w = warped[v];
    product[v] = w * target_image[v];
    energy[v] = w * w;
}
