// fold_refresh.wgsl: after a sweep of the fold push, the next sweep's list: the voxels it lifts
// (lift_rule.wgsl) where the sweep can have changed them. A push moves the six stencil
// neighbours of its voxel, which changes det J within two steps of it (L1), so each voxel of
// this sweep's list looks at the 25 voxels within two steps, itself included; every voxel to
// lift lies there (it was listed, or a push changed it). A voxel several invocations see is
// looked at once, by the one that stamps it with the sweep first (neighbourhoods of a cluster
// of listed voxels overlap up to 25 times).
//
// Bindings (group 0):
//   0 uniform  RefreshParams
//   1 storage  voxels: array<u32>           this sweep's list (push_list.wgsl)
//   2 storage  field: array<f32>            3 floats per voxel (u, mm)
//   3 storage  held: array<f32>             1 float per voxel (bone numbers, 0 for tissue)
//   4 storage  next: array<u32>             the next sweep's list, appended to
//   5 storage  looked: array<atomic<u32>>   1 per voxel: the sweep that last looked at it, 0 never
//   6 storage  state: array<atomic<u32>>    the push's state
// Dispatch: indirect, fold_advance.wgsl's workgroup counts for the refresh (one invocation
// per listed voxel).

// Keep in sync with abi::RefreshParams.
struct RefreshParams {
    dims: vec4<u32>,             // nx, ny, nz, unused
    mm_to_index: array<vec4<f32>, 3>,
    spared: u32,                 // as CandidateParams
    threshold: f32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: RefreshParams;
@group(0) @binding(1) var<storage, read> voxels: array<u32>;
@group(0) @binding(2) var<storage, read> field: array<f32>;
@group(0) @binding(3) var<storage, read> held: array<f32>;
@group(0) @binding(4) var<storage, read_write> next: array<u32>;
@group(0) @binding(5) var<storage, read_write> looked: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read_write> state: array<atomic<u32>>;

// This sweep's list entry `t` counts through: the buckets one after the other.
fn listed_voxel(t: u32) -> u32 {
    var before = 0u;
    for (var c = 0u; c < COLOURS; c = c + 1u) {
        let count = atomicLoad(&state[STATE_CURRENT + c]);
        if (t < before + count) {
            return voxels[bucket_start(c, params.dims.xyz) + t - before];
        }
        before = before + count;
    }
    return 0xffffffffu;
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let n = listed_voxel(entry_of(gid));
    if (n == 0xffffffffu) {
        return;
    }
    let sweep = atomicLoad(&state[STATE_SWEEP]);
    let d = vec3<i32>(params.dims.xyz);
    let c = vec3<i32>(voxel_of(n));
    for (var dz = -2; dz <= 2; dz = dz + 1) {
        for (var dy = -2; dy <= 2; dy = dy + 1) {
            for (var dx = -2; dx <= 2; dx = dx + 1) {
                let p = c + vec3<i32>(dx, dy, dz);
                let near = abs(dx) + abs(dy) + abs(dz) <= 2;
                if (near && all(p >= vec3<i32>(0)) && all(p < d)) {
                    let q = vec3<u32>(p);
                    let v = voxel_index(q.x, q.y, q.z, params.dims.xyz);
                    if (atomicMax(&looked[v], sweep) < sweep) {
                        let code = lift_code(v, det_at(q, v));
                        if (code > 0.0) {
                            append(v, q, code);
                        }
                    }
                }
            }
        }
    }
}
