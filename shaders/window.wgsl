// window.wgsl: the statistics of one local-correlation window from its box sums
// (correlation/local_moments.wgsl); shared by lncc, lncc_terms and dense/dense_force.
// Mirrored in src/cpu/window.rs.

// Voxels of the window along one axis at coordinate c of n, radius r.
fn window_length(c: u32, n: u32, r: u32) -> u32 {
    return min(c + r + 1u, n) - (max(c, r) - r);
}

// The window of voxel v (index i, j, k) on a grid `d` (nx, ny, nz, radius): with n its voxels,
// means ma = Σa / n, mb = Σb / n, variances va = Σa² / n − ma², vb likewise, covariance
// cab = Σab / n − ma mb, and whether either image is flat in it (its variance within f32
// rounding of its mean square, 1e-6 of it).
struct Window {
    n: f32,
    ma: f32,
    mb: f32,
    va: f32,
    vb: f32,
    cab: f32,
    flat: bool,
}

fn window_at(sums: array<f32, 5>, d: vec4<u32>, i: u32, j: u32, k: u32) -> Window {
    let n = f32(window_length(i, d.x, d.w) * window_length(j, d.y, d.w)
        * window_length(k, d.z, d.w));
    let ma = sums[0] / n;
    let mb = sums[1] / n;
    let saa = sums[2] / n;
    let sbb = sums[3] / n;
    let va = saa - ma * ma;
    let vb = sbb - mb * mb;
    let cab = sums[4] / n - ma * mb;
    return Window(n, ma, mb, va, vb, cab, va <= 1e-6 * saa || vb <= 1e-6 * sbb);
}
