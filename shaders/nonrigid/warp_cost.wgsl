// warp_cost.wgsl: the image part of one evaluation of the non-rigid cost, on the device.
//
// As rbf_grad: the moving image I0 sampled through the lattice-interpolated warp,
// W(x) = I0(x + R(x)) (0 with no gradient outside I0), against the target T. Here the coverage
// mask c (1 where I0 holds data from the source scan) is applied on the device and nothing per
// voxel is read back: per voxel, the masked gradient c · 2 (W − T) ∇I0(x + R(x)) (world mm)
// for lattice_splat; per row of x, Σ c (W − T)² in x order for sum_chunks.
//
// Bindings (group 0):
//   0 uniform  RbfGradParams
//   1 storage  lattice: array<f32>    3 floats (R, mm) per lattice node
//   2 storage  moving: array<f32>     I0 on the target grid
//   3 storage  fixed: array<f32>      the target T
//   4 storage  covered: array<f32>    coverage c per voxel (counted where is_covered)
//   5 storage  gradient: array<f32>   3 floats per voxel (read_write)
//   6 storage  rows: array<f32>       1 float per row (j, k), index j + ny k (read_write)
// Dispatch: workgroups (ceil(ny/8), ceil(nz/8), 1); one invocation per row.

@group(0) @binding(0) var<uniform> params: RbfGradParams;
@group(0) @binding(1) var<storage, read> lattice: array<f32>;
@group(0) @binding(2) var<storage, read> moving: array<f32>;
@group(0) @binding(3) var<storage, read> fixed: array<f32>;
@group(0) @binding(4) var<storage, read> covered: array<f32>;
@group(0) @binding(5) var<storage, read_write> gradient: array<f32>;
@group(0) @binding(6) var<storage, read_write> rows: array<f32>;

fn sampled_value(index: u32) -> f32 {
    return moving[index];
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    let j = gid.x;
    let k = gid.y;
    if (j >= d.y || k >= d.z) {
        return;
    }
    var sum = 0.0;
    for (var i = 0u; i < d.x; i = i + 1u) {
        let v = voxel_index(i, j, k, d.xyz);
        let s = warped_sample(i, j, k, fixed[v]);
        let c = select(0.0, 1.0, is_covered(covered[v]));
        let e = s.x - fixed[v];
        sum = sum + c * e * e;
        let g = s.yzw;
        gradient[3u * v] = c * g.x;
        gradient[3u * v + 1u] = c * g.y;
        gradient[3u * v + 2u] = c * g.z;
    }
    rows[j + d.y * k] = sum;
}
