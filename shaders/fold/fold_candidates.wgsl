// fold_candidates.wgsl: the first list of a pass of the fold push (src/images/unfold.rs): every
// voxel the pass lifts (lift_rule.wgsl's codes 1 and 2), appended to its colour's bucket, over
// the whole grid; fold_refresh.wgsl makes the next lists around the pushed voxels.
//
// Bindings (group 0):
//   0 uniform  CandidateParams
//   1 storage  det: array<f32>              1 float per voxel
//   2 storage  held: array<f32>             1 float per voxel (bone numbers, 0 for tissue)
//   3 storage  next: array<u32>             the list, as long as the grid (push_list.wgsl)
//   4 storage  state: array<atomic<u32>>    the push's state, zero before
// Dispatch: workgroups (ceil(nx/4), ceil(ny/4), ceil(nz/4)).

// Keep in sync with abi::CandidateParams.
struct CandidateParams {
    dims: vec4<u32>,   // nx, ny, nz, unused
    threshold: f32,    // det J at or below which a voxel is lifted
    spared: u32,       // 1: voxels enclosed by two bones; 2: every bone contact
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: CandidateParams;
@group(0) @binding(1) var<storage, read> det: array<f32>;
@group(0) @binding(2) var<storage, read> held: array<f32>;
@group(0) @binding(3) var<storage, read_write> next: array<u32>;
@group(0) @binding(4) var<storage, read_write> state: array<atomic<u32>>;

@compute @workgroup_size(4, 4, 4)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = params.dims.xyz;
    if (gid.x >= d.x || gid.y >= d.y || gid.z >= d.z) {
        return;
    }
    let v = voxel_index(gid.x, gid.y, gid.z, d);
    let code = lift_code(v, det[v]);
    if (code > 0.0) {
        append(v, gid, code);
    }
}
