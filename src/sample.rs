//! Trilinear and nearest sampling of a volume at a continuous voxel index, by hand: the CPU
//! twin of shaders/sample.wgsl, which the CPU kernels use, and the one sampling the host's
//! own per-point work (pictures, points) shares with them.

/// Flat index of voxel (i, j, k) in an x-fastest volume of size dims (common.wgsl's
/// voxel_index).
pub fn voxel_index(i: u32, j: u32, k: u32, dims: [u32; 3]) -> u32 {
    i + dims[0] * (j + dims[1] * k)
}

/// True when q lies within half a voxel of the outer voxel centres on every axis.
pub fn inside_source(q: [f32; 3], dims: [u32; 3]) -> bool {
    (0..3).all(|a| q[a] >= -0.5 && q[a] <= dims[a] as f32 - 0.5)
}

/// Trilinear value of `source` at continuous index q; `background` outside
/// [-0.5, n - 0.5] on any axis (NaN coordinates count as outside).
pub fn trilinear(source: &[f32], q: [f32; 3], dims: [u32; 3], background: f32) -> f32 {
    if !inside_source(q, dims) {
        return background;
    }
    trilinear_with_gradient(source, q, dims)[0]
}

/// The value of the voxel whose centre is nearest to q (ties round up); `background` outside.
pub fn nearest(source: &[f32], q: [f32; 3], dims: [u32; 3], background: f32) -> f32 {
    if !inside_source(q, dims) {
        return background;
    }
    let i: [u32; 3] =
        std::array::from_fn(|a| ((q[a] + 0.5).floor() as i32).clamp(0, dims[a] as i32 - 1) as u32);
    source[voxel_index(i[0], i[1], i[2], dims) as usize]
}

/// Value and index-space gradient of the trilinear interpolant at q (caller checks
/// [`inside_source`]): [value, d/di, d/dj, d/dk].
pub fn trilinear_with_gradient(source: &[f32], q: [f32; 3], dims: [u32; 3]) -> [f32; 4] {
    let base = q.map(f32::floor);
    let t = [q[0] - base[0], q[1] - base[1], q[2] - base[2]];
    let top = dims.map(|d| d as i32 - 1);
    let i0: [u32; 3] = std::array::from_fn(|a| (base[a] as i32).clamp(0, top[a]) as u32);
    let i1: [u32; 3] = std::array::from_fn(|a| (base[a] as i32 + 1).clamp(0, top[a]) as u32);
    let v = |x: u32, y: u32, z: u32| source[voxel_index(x, y, z, dims) as usize];
    let v000 = v(i0[0], i0[1], i0[2]);
    let v100 = v(i1[0], i0[1], i0[2]);
    let v010 = v(i0[0], i1[1], i0[2]);
    let v110 = v(i1[0], i1[1], i0[2]);
    let v001 = v(i0[0], i0[1], i1[2]);
    let v101 = v(i1[0], i0[1], i1[2]);
    let v011 = v(i0[0], i1[1], i1[2]);
    let v111 = v(i1[0], i1[1], i1[2]);
    let c00 = (1.0 - t[0]) * v000 + t[0] * v100;
    let c10 = (1.0 - t[0]) * v010 + t[0] * v110;
    let c01 = (1.0 - t[0]) * v001 + t[0] * v101;
    let c11 = (1.0 - t[0]) * v011 + t[0] * v111;
    let c0 = (1.0 - t[1]) * c00 + t[1] * c10;
    let c1 = (1.0 - t[1]) * c01 + t[1] * c11;
    let value = (1.0 - t[2]) * c0 + t[2] * c1;
    let dz = c1 - c0;
    let dy = (1.0 - t[2]) * (c10 - c00) + t[2] * (c11 - c01);
    let (e00, e10, e01, e11) = (v100 - v000, v110 - v010, v101 - v001, v111 - v011);
    let dx =
        (1.0 - t[2]) * ((1.0 - t[1]) * e00 + t[1] * e10) + t[2] * ((1.0 - t[1]) * e01 + t[1] * e11);
    [value, dx, dy, dz]
}
