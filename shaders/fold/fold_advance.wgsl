// fold_advance.wgsl: between two sweeps of the fold push (src/images/unfold.rs), on the
// device so that the host need not read each sweep's list: counts the sweeps that left only
// bone contacts, ends the pass (no voxel left to lift, the most sweeps run, or only bone
// contacts left for long enough), else makes the next list this sweep's and writes the
// workgroup counts of the sweep's dispatches (x, y, z each: the colours' pushes, then the
// refresh). Once ended, every count is zero and the
// dispatches the host recorded after it do nothing.
//
// Bindings (group 0):
//   0 uniform  AdvanceParams
//   1 storage  state: array<u32>   the push's state (push_list.wgsl)
//   2 storage  args: array<u32>    3 × 28 workgroup counts
// Dispatch: workgroups (1, 1, 1).

// Keep in sync with abi::AdvanceParams.
struct AdvanceParams {
    most_sweeps: u32,       // the pass ends after these
    contacts_alone: u32,    // ... or after these leave only bone contacts
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: AdvanceParams;
@group(0) @binding(1) var<storage, read_write> state: array<u32>;
@group(0) @binding(2) var<storage, read_write> args: array<u32>;

// Workgroup counts covering `count` list entries (entry_of).
fn write_args(slot: u32, count: u32) {
    let groups = (count + GROUP - 1u) / GROUP;
    let at = 3u * slot;
    args[at] = min(groups, ROW_GROUPS);
    args[at + 1u] = (groups + ROW_GROUPS - 1u) / ROW_GROUPS;
    args[at + 2u] = 1u;
}

fn stop() {
    state[STATE_STOPPED] = 1u;
    for (var c = 0u; c < COLOURS; c = c + 1u) {
        state[STATE_CURRENT + c] = 0u;
    }
    for (var slot = 0u; slot <= COLOURS; slot = slot + 1u) {
        write_args(slot, 0u);
    }
}

@compute @workgroup_size(1, 1, 1)
fn main() {
    if (state[STATE_STOPPED] == 1u) {
        return;
    }
    if (state[STATE_SWEEP] > 0u) {
        let alone = select(0u, state[STATE_CONTACTS_ALONE] + 1u, state[STATE_LIFTED] == 0u);
        state[STATE_CONTACTS_ALONE] = alone;
    }
    var total = 0u;
    for (var c = 0u; c < COLOURS; c = c + 1u) {
        total = total + state[STATE_NEXT + c];
    }
    let run = state[STATE_SWEEP] >= params.most_sweeps;
    if (total == 0u || run || state[STATE_CONTACTS_ALONE] >= params.contacts_alone) {
        stop();
        return;
    }
    state[STATE_SWEEP] = state[STATE_SWEEP] + 1u;
    state[STATE_LIFTED] = 0u;
    for (var c = 0u; c < COLOURS; c = c + 1u) {
        let count = state[STATE_NEXT + c];
        state[STATE_CURRENT + c] = count;
        state[STATE_NEXT + c] = 0u;
        write_args(c, count);
    }
    write_args(COLOURS, total);
}
