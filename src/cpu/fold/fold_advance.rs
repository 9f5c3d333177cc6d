//! CPU twin of shaders/fold/fold_advance.wgsl.

use crate::abi::push_state::{
    COLOURS, CONTACTS_ALONE, CURRENT, GROUP, LIFTED, NEXT, ROW_GROUPS, STOPPED, SWEEP,
};
use crate::abi::AdvanceParams;

/// Ends the pass in `state`, or makes the next list the sweep's; the sweep's workgroup counts
/// into `args`.
pub fn fold_advance(params: &AdvanceParams, state: &mut [u32], args: &mut [u32]) {
    if state[STOPPED] == 1 {
        return;
    }
    if state[SWEEP] > 0 {
        state[CONTACTS_ALONE] = match state[LIFTED] {
            0 => state[CONTACTS_ALONE] + 1,
            _ => 0,
        };
    }
    let total: u32 = state[NEXT..NEXT + COLOURS].iter().sum();
    let run = state[SWEEP] >= params.most_sweeps;
    if total == 0 || run || state[CONTACTS_ALONE] >= params.contacts_alone {
        stop(state, args);
        return;
    }
    state[SWEEP] += 1;
    state[LIFTED] = 0;
    for c in 0..COLOURS {
        let count = state[NEXT + c];
        state[CURRENT + c] = count;
        state[NEXT + c] = 0;
        write_args(args, c, count);
    }
    write_args(args, COLOURS, total);
}

fn stop(state: &mut [u32], args: &mut [u32]) {
    state[STOPPED] = 1;
    state[CURRENT..CURRENT + COLOURS].fill(0);
    for slot in 0..=COLOURS {
        write_args(args, slot, 0);
    }
}

/// Workgroup counts covering `count` list entries.
fn write_args(args: &mut [u32], slot: usize, count: u32) {
    let groups = count.div_ceil(GROUP);
    let at = 3 * slot;
    args[at] = groups.min(ROW_GROUPS);
    args[at + 1] = groups.div_ceil(ROW_GROUPS);
    args[at + 2] = 1;
}
