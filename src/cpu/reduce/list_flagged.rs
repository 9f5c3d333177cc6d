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
    let [_, per_chunk, chunks, _] = params.counts.map(|c| c as usize);
    let chunked = flags.chunks(per_chunk).zip(offsets).take(chunks);
    for (c, (chunk, &offset)) in chunked.enumerate() {
        let mut at = offset as usize;
        for (k, &flag) in chunk.iter().enumerate() {
            if flag > 0.0 {
                indices[at] = (c * per_chunk + k) as u32;
                values[at] = flag;
                at += 1;
            }
        }
    }
}
