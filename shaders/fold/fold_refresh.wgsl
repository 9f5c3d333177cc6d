// fold_refresh.wgsl: after a sweep of the fold push, the flags of the voxels it may lift next
// (lift_rule.wgsl), brought up to date where the sweep can have changed them: a push moves the
// six stencil neighbours of its voxel, which changes det J within two steps of it (L1), so each
// listed voxel refreshes the 25 voxels within two steps. Elsewhere the flags are unchanged.
// Invocations whose neighbourhoods overlap write the same value (computed from the same field).
//
// Bindings (group 0):
//   0 uniform  RefreshParams
//   1 storage  voxels: array<u32>   the sweep's voxels; this dispatch's are first..end
//   2 storage  field: array<f32>    3 floats per voxel (u, mm)
//   3 storage  held: array<f32>     1 float per voxel (bone numbers, 0 for tissue)
//   4 storage  flags: array<f32>    1 float per voxel, written in place
// Dispatch: workgroups (ceil((end - first) / 64), 1, 1).

// Keep in sync with abi::RefreshParams.
struct RefreshParams {
    dims: vec4<u32>,             // nx, ny, nz, unused
    mm_to_index: array<vec4<f32>, 3>,
    first: u32,
    end: u32,
    spared: u32,                 // as CandidateParams
    threshold: f32,
}

@group(0) @binding(0) var<uniform> params: RefreshParams;
@group(0) @binding(1) var<storage, read> voxels: array<u32>;
@group(0) @binding(2) var<storage, read> field: array<f32>;
@group(0) @binding(3) var<storage, read> held: array<f32>;
@group(0) @binding(4) var<storage, read_write> flags: array<f32>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = params.first + gid.x;
    if (t >= params.end) {
        return;
    }
    let d = vec3<i32>(params.dims.xyz);
    let c = vec3<i32>(voxel_of(voxels[t]));
    for (var dz = -2; dz <= 2; dz = dz + 1) {
        for (var dy = -2; dy <= 2; dy = dy + 1) {
            for (var dx = -2; dx <= 2; dx = dx + 1) {
                let p = c + vec3<i32>(dx, dy, dz);
                let near = abs(dx) + abs(dy) + abs(dz) <= 2;
                if (near && all(p >= vec3<i32>(0)) && all(p < d)) {
                    let q = vec3<u32>(p);
                    let v = voxel_index(q.x, q.y, q.z, params.dims.xyz);
                    flags[v] = lift_code(v, det_at(q, v));
                }
            }
        }
    }
}
