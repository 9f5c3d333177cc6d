//! CPU twin of shaders/reduce/list_flagged.wgsl.

use crate::abi::ListParams;

/// Writes the flagged values (> 0) of `flags` and their indices into `indices` and `values`,
/// chunk by chunk from each chunk's offset in `offsets`.
pub fn list_flagged(
    params: &ListParams,
    flags: &[f32],
    offsets: &[u32],
    indices: &mut [u32],
    values: &mut [f32],
) {
    let [len, per_chunk, chunks, _] = params.counts.map(|c| c as usize);
    for c in 0..chunks {
        let mut at = offsets[c] as usize;
        for v in c * per_chunk..((c + 1) * per_chunk).min(len) {
            let flag = flags[v];
            if flag > 0.0 {
                indices[at] = v as u32;
                values[at] = flag;
                at += 1;
            }
        }
    }
}
