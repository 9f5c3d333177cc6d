//! CPU twin of shaders/window.wgsl: the statistics of one local-correlation window from its
//! box sums, shared by the twins of lncc, lncc_terms and dense_force.

use crate::abi::LOCAL_MOMENTS;

/// Voxels of the window along one axis at coordinate c of n, radius r.
fn window_length(c: u32, n: u32, r: u32) -> u32 {
    (c + r + 1).min(n) - (c.max(r) - r)
}

/// The statistics of one window (Window in shaders/window.wgsl).
pub(crate) struct Window {
    pub(crate) n: f32,
    pub(crate) ma: f32,
    pub(crate) mb: f32,
    pub(crate) va: f32,
    pub(crate) vb: f32,
    pub(crate) cab: f32,
    pub(crate) flat: bool,
}

/// The window of voxel v (index i, j, k) on a grid `d` (nx, ny, nz, radius) from its box
/// sums (window_at in shaders/window.wgsl).
#[inline(always)]
pub(crate) fn window_at(sums: &[f32], v: usize, d: [u32; 4], [i, j, k]: [u32; 3]) -> Window {
    let n = (window_length(i, d[0], d[3])
        * window_length(j, d[1], d[3])
        * window_length(k, d[2], d[3])) as f32;
    let s = &sums[LOCAL_MOMENTS * v..LOCAL_MOMENTS * (v + 1)];
    let (ma, mb) = (s[0] / n, s[1] / n);
    let (saa, sbb) = (s[2] / n, s[3] / n);
    let va = saa - ma * ma;
    let vb = sbb - mb * mb;
    let cab = s[4] / n - ma * mb;
    let flat = va <= 1e-6 * saa || vb <= 1e-6 * sbb;
    Window {
        n,
        ma,
        mb,
        va,
        vb,
        cab,
        flat,
    }
}
