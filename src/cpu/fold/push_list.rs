//! CPU twin of shaders/fold/push_list.wgsl and list_append.wgsl: the fold push's lists, each
//! colour's voxels in a bucket of its own, and the state that counts them (abi::push_state).

use crate::abi::push_state::{COLOURS, CURRENT, LIFTED, NEXT};

/// The colour of voxel p (i, j, k): two voxels of one colour lie at least three steps apart.
pub fn colour_of(p: [usize; 3]) -> usize {
    p[0] % 3 + 3 * (p[1] % 3) + 9 * (p[2] % 3)
}

/// Voxels of colour c in a grid of `dims`.
fn colour_size(c: usize, dims: [usize; 3]) -> usize {
    let residue = [c % 3, c / 3 % 3, c / 9];
    (0..3).map(|a| (dims[a] + 2 - residue[a]) / 3).product()
}

/// Where colour c's bucket starts in a list.
fn bucket_start(c: usize, dims: [usize; 3]) -> usize {
    (0..c).map(|b| colour_size(b, dims)).sum()
}

/// Colour c's voxels in the sweep's list `voxels`, as many as `state` counts.
pub fn bucket<'a>(voxels: &'a [u32], state: &[u32], c: usize, dims: [usize; 3]) -> &'a [u32] {
    let start = bucket_start(c, dims);
    &voxels[start..start + state[CURRENT + c] as usize]
}

/// The sweep's list `voxels`, bucket after bucket (the order of fold_refresh.wgsl's entries).
pub fn listed(voxels: &[u32], state: &[u32], dims: [usize; 3]) -> Vec<u32> {
    (0..COLOURS)
        .flat_map(|c| bucket(voxels, state, c, dims))
        .copied()
        .collect()
}

/// The next list and the state that counts it, appended to (list_append.wgsl).
pub struct Appender<'a> {
    /// The grid's nx, ny, nz.
    pub dims: [usize; 3],
    /// The next list.
    pub next: &'a mut [u32],
    /// The push's state.
    pub state: &'a mut [u32],
}

impl Appender<'_> {
    /// Appends voxel v, at p, with lift code `code` (2: a bone contact).
    pub fn append(&mut self, v: usize, p: [usize; 3], code: f32) {
        let c = colour_of(p);
        let slot = self.state[NEXT + c] as usize;
        self.state[NEXT + c] += 1;
        self.next[bucket_start(c, self.dims) + slot] = v as u32;
        if code == 1.0 {
            self.state[LIFTED] += 1;
        }
    }
}
