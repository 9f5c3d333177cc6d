// gain_ratio.wgsl: the gain on the smoothed grid, g = G∗(W·T) / G∗(W·W), kept within a factor
// `most` of 1 (a wider ratio is anatomy, not bias), and 1 where the smoothed energy is at or
// below the floor (where the moving image is nearly empty the ratio means nothing).
//
// Bindings (group 0):
//   0 uniform  GainParams (dims: the smoothed grid)
//   1 storage  product: array<f32>  G∗(W·T)
//   2 storage  energy: array<f32>   G∗(W·W)
//   3 storage  gain: array<f32>     (read_write)
// Dispatch: workgroups (ceil(voxels / 64), 1, 1).

@group(0) @binding(0) var<uniform> params: GainParams;
@group(0) @binding(1) var<storage, read> product: array<f32>;
@group(0) @binding(2) var<storage, read> energy: array<f32>;
@group(0) @binding(3) var<storage, read_write> gain: array<f32>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let v = gid.x;
    if (v >= params.dims.w) {
        return;
    }
    let e = energy[v];
    let most = params.limits.y;
    if (e > params.limits.x) {
        gain[v] = clamp(product[v] / e, 1.0 / most, most);
    } else {
        gain[v] = 1.0;
    }
}
