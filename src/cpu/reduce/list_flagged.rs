//! CPU twin of shaders/reduce/list_flagged.wgsl.

use crate::abi::ListParams;
use rayon::prelude::*;

/// Writes the flagged values (> 0) of `flags` and their indices into `indices` and `values`,
/// chunk by chunk from each chunk's offset in `offsets` (the chunks in parallel: each writes
/// its own part of the list, from its offset to the next chunk's).
pub fn list_flagged(
    params: &ListParams,
    flags: &[f32],
    offsets: &[u32],
    indices: &mut [u32],
    values: &mut [f32],
) {
    let [len, per_chunk, chunks, _] = params.counts.map(|c| c as usize);
    let parts = split_at_offsets(indices, &offsets[..chunks])
        .into_iter()
        .zip(split_at_offsets(values, &offsets[..chunks]));
    let chunked: Vec<_> = flags[..len]
        .chunks(per_chunk)
        .enumerate()
        .zip(parts)
        .collect();
    chunked
        .into_par_iter()
        .for_each(|((c, chunk), (indices, values))| {
            let mut at = 0;
            for (k, &flag) in chunk.iter().enumerate() {
                if flag > 0.0 {
                    indices[at] = (c * per_chunk + k) as u32;
                    values[at] = flag;
                    at += 1;
                }
            }
        });
}

/// `list` cut at each chunk's offset (the first is 0): each chunk's part of it.
fn split_at_offsets<'a, T>(list: &'a mut [T], offsets: &[u32]) -> Vec<&'a mut [T]> {
    let mut parts = Vec::with_capacity(offsets.len());
    let mut rest = list;
    for pair in offsets.windows(2) {
        let (part, after) = rest.split_at_mut((pair[1] - pair[0]) as usize);
        parts.push(part);
        rest = after;
    }
    if !offsets.is_empty() {
        parts.push(rest);
    }
    parts
}
