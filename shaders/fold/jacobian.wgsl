// jacobian.wgsl: det(I + du/dx) of the map x -> x + u(x) at every voxel, u a displacement field
// in world mm on this grid. du/d(index) by central differences (one-sided at the volume's
// faces), then du/dx = du/d(index) · d(index)/dx with d(index)/dx the inverse of the grid's
// linear part. A determinant <= 0 means the map folds there.
//
// Bindings (group 0):
//   0 uniform  JacobianParams
//   1 storage  field: array<f32>  3 floats per voxel
//   2 storage  det: array<f32>    1 float per voxel (read_write)
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::JacobianParams.
struct JacobianParams {
    dims: vec4<u32>,     // nx, ny, nz, unused
    mm_to_index: array<vec4<f32>, 3>,
}

@group(0) @binding(0) var<uniform> params: JacobianParams;
@group(0) @binding(1) var<storage, read> field: array<f32>;
@group(0) @binding(2) var<storage, read_write> det: array<f32>;

fn displacement(i: u32, j: u32, k: u32) -> vec3<f32> {
    let n = 3u * voxel_index(i, j, k, params.dims.xyz);
    return vec3<f32>(field[n], field[n + 1u], field[n + 2u]);
}

// Central difference along one axis at coordinate c of n (one-sided at the ends).
fn difference(lo: vec3<f32>, hi: vec3<f32>, c: u32, n: u32) -> vec3<f32> {
    if (n == 1u) {
        return vec3<f32>(0.0);
    }
    if (c == 0u || c == n - 1u) {
        return hi - lo;
    }
    return (hi - lo) * 0.5;
}

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let i = gid.x;
    let j = gid.y;
    let k = gid.z;
    let dx = difference(displacement(max(i, 1u) - 1u, j, k), displacement(min(i + 1u, d.x - 1u), j, k), i, d.x);
    let dy = difference(displacement(i, max(j, 1u) - 1u, k), displacement(i, min(j + 1u, d.y - 1u), k), j, d.y);
    let dz = difference(displacement(i, j, max(k, 1u) - 1u), displacement(i, j, min(k + 1u, d.z - 1u)), k, d.z);
    // Row r of du/dx: component r's index derivatives times d(index)/dx.
    let m0 = params.mm_to_index[0].xyz;
    let m1 = params.mm_to_index[1].xyz;
    let m2 = params.mm_to_index[2].xyz;
    let r0 = dx.x * m0 + dy.x * m1 + dz.x * m2 + vec3<f32>(1.0, 0.0, 0.0);
    let r1 = dx.y * m0 + dy.y * m1 + dz.y * m2 + vec3<f32>(0.0, 1.0, 0.0);
    let r2 = dx.z * m0 + dy.z * m1 + dz.z * m2 + vec3<f32>(0.0, 0.0, 1.0);
    det[voxel_index(i, j, k, d.xyz)] = det3(r0, r1, r2);
}
