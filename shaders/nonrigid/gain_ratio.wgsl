// gain_ratio.wgsl: the gain on the smoothed grid, g = G∗(W·T) / G∗(W·W), kept within a factor
// `most` of 1 (a wider ratio is anatomy, not bias), and 1 where the smoothed energy is at or
// below the floor (where the moving image is nearly empty the ratio means nothing).
//
// Bindings (group 0):
//   0 uniform  GainParams (dims: the smoothed grid)
//   1 storage  product: array<f32>  G∗(W·T)
//   2 storage  energy: array<f32>   G∗(W·W)
//   3 storage  gain: array<f32>     (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)): a 1-D dispatch of a paper-sized
// grid would exceed 65535 workgroups.

@group(0) @binding(0) var<uniform> params: GainParams;
@group(0) @binding(1) var<storage, read> product: array<f32>;
@group(0) @binding(2) var<storage, read> energy: array<f32>;
@group(0) @binding(3) var<storage, read_write> gain: array<f32>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let e = energy[v];
    let most = params.most;
    if (e > params.floor) {
        gain[v] = clamp(product[v] / e, 1.0 / most, most);
    } else {
        gain[v] = 1.0;
    }
}
