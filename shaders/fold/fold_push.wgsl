// fold_push.wgsl: one colour's pushes in a sweep of the fold push (src/images/unfold.rs has
// the method and the sweeps). Each listed voxel n still at or below the threshold moves its
// stencil neighbours that may move along the gradient of its own det J, far enough together
// to lift it (linearised) to the target: the folding correction NiftyReg applies to spline
// grids, on a dense field. A neighbour q may move unless its displacement is its bone's motion
// (rigid) or it was blocked in this sweep or the last. A move that would carry q's source point
// into a bone is shortened to 1/2, 1/4, 1/8; where none stays out, q takes the motion of the
// bone holding n extended past it (2 u(n) - u(opposite), where n and the neighbour across it
// move with one bone), else q is blocked (stamped with the sweep).
//
// The voxels of one colour (i mod 3, j mod 3, k mod 3) lie at least three steps apart, so the
// neighbourhoods their pushes read and write never overlap: every invocation writes the field
// in place, in any order, with the same result, and each colour sees the colours before it.
// The colour's voxels are its bucket of the sweep's list, as many as the state counts
// (push_list.wgsl).
//
// Bindings (group 0):
//   0 uniform  PushParams
//   1 storage  voxels: array<u32>    the sweep's list (push_list.wgsl)
//   2 storage  rigid: array<f32>     1 float per voxel (> 0: at its bone's motion)
//   3 storage  labels: array<f32>    the source label map, 1 float per voxel
//   4 storage  field: array<f32>     3 floats per voxel (u, mm), written in place
//   5 storage  blocked: array<u32>   1 per voxel: the sweep it was last blocked in, 0 never
//   6 storage  state: array<u32>     the push's state
// Dispatch: indirect, fold_advance.wgsl's workgroup counts for the colour.

// Keep in sync with abi::PushParams.
struct PushParams {
    geometry: ResampleParams,    // field grid -> source label grid (bone_lookup.wgsl)
    codes: LabelCodes,           // the bones
    dims: vec4<u32>,             // nx, ny, nz of the field's grid, unused
    mm_to_index: array<vec4<f32>, 3>,
    colour: u32,                 // the colour pushed (push_list.wgsl)
    pad0: u32,
    pad1: u32,
    pad2: u32,
    largest_step: f32,           // longest move of one neighbour (mm)
    threshold: f32,              // det J at or below which a voxel is pushed
    aim: f32,                    // det J a push aims for
    pad3: u32,
}

@group(0) @binding(0) var<uniform> params: PushParams;
@group(0) @binding(1) var<storage, read> voxels: array<u32>;
@group(0) @binding(2) var<storage, read> rigid: array<f32>;
@group(0) @binding(3) var<storage, read> labels: array<f32>;
@group(0) @binding(4) var<storage, read_write> field: array<f32>;
@group(0) @binding(5) var<storage, read_write> blocked: array<u32>;
@group(0) @binding(6) var<storage, read> state: array<u32>;

fn sampled_value(index: u32) -> f32 {
    return labels[index];
}

fn set_displacement(v: u32, u: vec3<f32>) {
    field[3u * v] = u.x;
    field[3u * v + 1u] = u.y;
    field[3u * v + 2u] = u.z;
}

fn in_bone(v: u32, u: vec3<f32>) -> bool {
    return bone_at(vec3<f32>(voxel_of(v)), u) > 0u;
}

// `shift` no longer than the largest step.
fn clamp_length(shift: vec3<f32>) -> vec3<f32> {
    let length_sq = dot3(shift, shift);
    let most = params.largest_step;
    if (length_sq > most * most) {
        return shift * (most / sqrt(length_sq));
    }
    return shift;
}

// Moves neighbour q of voxel n (the neighbour across n: `opposite`) by `shift`, shortened
// where it would enter a bone; else extends n's bone to it; else stamps it blocked.
fn move_neighbour(n: u32, q: u32, opposite: u32, shift: vec3<f32>) {
    let start = displacement(q);
    let inside = in_bone(q, start);
    var f = 1.0;
    for (var k = 0u; k < 4u; k = k + 1u) {
        let moved = start + shift * f;
        if (inside || !in_bone(q, moved)) {
            set_displacement(q, moved);
            return;
        }
        f = f * 0.5;
    }
    let bone = rigid[n];
    if (bone > 0.0 && opposite != n && rigid[opposite] == bone) {
        set_displacement(q, 2.0 * displacement(n) - displacement(opposite));
        return;
    }
    blocked[q] = state[STATE_SWEEP];
}

fn may_move(n: u32, q: u32) -> bool {
    let stamp = blocked[q];
    return q != n && rigid[q] <= 0.0 && (stamp == 0u || stamp + 1u < state[STATE_SWEEP]);
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let t = entry_of(gid);
    if (t >= state[STATE_CURRENT + params.colour]) {
        return;
    }
    let n = voxels[bucket_start(params.colour, params.dims.xyz) + t];
    let c = voxel_of(n);
    let now = det_and_gradient(c, n);
    if (now.det > params.threshold) {
        return;
    }
    // Each neighbour that may move, its gradient (hi: +g, lo: -g, times the arm's factor) and
    // the neighbour across n; decided before any moves, as the sum below needs them all.
    var q: array<u32, 6>;
    var gq: array<vec3<f32>, 6>;
    var across: array<u32, 6>;
    var count = 0u;
    var norm = 0.0;
    for (var a = 0u; a < 3u; a = a + 1u) {
        let s = arm(c, n, a);
        let g = now.gradient[a] * s.factor;
        if (may_move(n, s.hi)) {
            q[count] = s.hi;
            gq[count] = g;
            across[count] = s.lo;
            norm = norm + dot3(g, g);
            count = count + 1u;
        }
        if (may_move(n, s.lo)) {
            q[count] = s.lo;
            gq[count] = -g;
            across[count] = s.hi;
            norm = norm + dot3(g, g);
            count = count + 1u;
        }
    }
    if (norm <= 1.1920929e-7) {
        return;
    }
    let step = (params.aim - now.det) / norm;
    for (var m = 0u; m < count; m = m + 1u) {
        move_neighbour(n, q[m], across[m], clamp_length(gq[m] * step));
    }
}
