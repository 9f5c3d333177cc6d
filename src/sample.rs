//! Trilinear and nearest sampling of a volume at a continuous voxel index, by hand: the CPU
//! twin of shaders/sample.wgsl (and of the lookups in geometry.wgsl, labels.wgsl and
//! bone_lookup.wgsl), which the CPU kernels use, and the one sampling the host's own per-point
//! work (pictures, points, the fold repair's host step) shares with them.

use crate::abi::{BoneLookupParams, LabelCodes, ResampleParams};

/// `std::array::from_fn` as a loop. The compiler may leave the closure of `from_fn` (or of an
/// array's `map`) behind a call, which also keeps it out of a caller's AVX2 build
/// (the CPU backend's notes); the closure of a loop it inlines.
#[inline(always)]
pub fn array_from<T: Copy + Default, const N: usize>(mut f: impl FnMut(usize) -> T) -> [T; N] {
    let mut out = [T::default(); N];
    for (i, o) in out.iter_mut().enumerate() {
        *o = f(i);
    }
    out
}

/// Flat index of voxel (i, j, k) in an x-fastest volume of size dims (common.wgsl's
/// voxel_index).
#[inline]
pub fn voxel_index(i: u32, j: u32, k: u32, dims: [u32; 3]) -> u32 {
    i + dims[0] * (j + dims[1] * k)
}

/// One row of a 3x4 affine applied to a point, summed left to right (common.wgsl).
#[inline]
pub fn affine_row(row: [f32; 4], p: [f32; 3]) -> f32 {
    row[0] * p[0] + row[1] * p[1] + row[2] * p[2] + row[3]
}

/// One row of a 3x3 linear map applied to a vector (common.wgsl).
#[inline]
pub fn linear_row(row: [f32; 4], v: [f32; 3]) -> f32 {
    row[0] * v[0] + row[1] * v[1] + row[2] * v[2]
}

/// The continuous source index of target voxel p's point displaced by u (world mm)
/// (geometry.wgsl).
#[inline]
pub fn source_index(g: &ResampleParams, p: [f32; 3], u: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|r| affine_row(g.index_to_source[r], p) + linear_row(g.mm_to_source[r], u))
}

/// 1 + the position of `label` in `codes`, 0 when it is none of them or negative (labels.wgsl).
#[inline]
pub fn code_index(codes: &LabelCodes, label: f32) -> u32 {
    if label < 0.0 {
        return 0;
    }
    let code = label as u32;
    (0..codes.count)
        .find(|&c| codes.list[(c / 4) as usize][(c % 4) as usize] == code)
        .map_or(0, |c| c + 1)
}

/// code_index of the source label (`labels`, codes as f32) nearest to target voxel p
/// displaced by u (mm); 0 outside the label map (bone_lookup.wgsl).
#[inline]
pub fn bone_at(params: &BoneLookupParams, labels: &[f32], p: [f32; 3], u: [f32; 3]) -> u32 {
    let q = source_index(&params.geometry, p, u);
    let g = params.geometry.source_dims;
    code_index(&params.codes, nearest(labels, q, [g[0], g[1], g[2]], -1.0))
}

/// True when q lies within half a voxel of the outer voxel centres on every axis.
#[inline]
pub fn inside_source(q: [f32; 3], dims: [u32; 3]) -> bool {
    (0..3).all(|a| inside_axis(q[a], dims[a]))
}

/// [`inside_source`] along one axis of n voxels.
#[inline]
pub fn inside_axis(q: f32, n: u32) -> bool {
    q >= -0.5 && q <= n as f32 - 0.5
}

/// ⌊x⌋, the same value as `f32::floor` for every f32 (NaN and ±∞ included). `f32::floor` is a
/// libm call on the baseline x86-64 target, which lacks SSE4.1's rounding instruction; the
/// sampling loops called it for 3.5% of a registration's CPU time. Below 2²³ in magnitude
/// adding and taking away 2²³ rounds to a whole number exactly, which is stepped down where it
/// rounded up; at or above it every f32 is already whole.
#[inline]
pub fn floor(x: f32) -> f32 {
    // |x| rounded to a whole number by the addition (exact below 2²³), stepped down where that
    // rounded up; chosen between rather than branched on, with no conversion to an integer,
    // so that loops over voxels vectorise.
    const WHOLE_FROM: f32 = 8_388_608.0;
    let rounded = ((x.abs() + WHOLE_FROM) - WHOLE_FROM).copysign(x);
    let stepped = if rounded > x { rounded - 1.0 } else { rounded };
    // At or above 2²³ every f32 is whole; NaN stays NaN.
    if x.is_nan() || x.abs() >= WHOLE_FROM {
        x
    } else {
        stepped
    }
}

/// Trilinear value of `source` at continuous index q; `background` outside
/// [-0.5, n - 0.5] on any axis (NaN coordinates count as outside).
#[inline]
pub fn trilinear(source: &[f32], q: [f32; 3], dims: [u32; 3], background: f32) -> f32 {
    if !inside_source(q, dims) {
        return background;
    }
    trilinear_with_gradient(source, q, dims)[0]
}

/// The value of the voxel whose centre is nearest to q (ties round up); `background` outside.
#[inline(always)]
pub fn nearest(source: &[f32], q: [f32; 3], dims: [u32; 3], background: f32) -> f32 {
    if !inside_source(q, dims) {
        return background;
    }
    let at = |a: usize| (floor(q[a] + 0.5) as i32).clamp(0, dims[a] as i32 - 1) as u32;
    source[voxel_index(at(0), at(1), at(2), dims) as usize]
}

/// Value and index-space gradient of the trilinear interpolant at q (caller checks
/// [`inside_source`]): [value, d/di, d/dj, d/dk].
#[inline]
pub fn trilinear_with_gradient(source: &[f32], q: [f32; 3], dims: [u32; 3]) -> [f32; 4] {
    let (v, t) = corners(source, q, dims);
    blend_corners(v, t)
}

/// The 8 voxels of `source` around continuous index q (x fastest: v000, v100, v010, v110,
/// v001, …; clamped to the volume, so any q may be asked) and q's fraction past the first
/// corner per axis: what [`blend_corners`] interpolates.
#[inline]
pub fn corners(source: &[f32], q: [f32; 3], dims: [u32; 3]) -> ([f32; 8], [f32; 3]) {
    let (at, t) = corner_indices(q, dims);
    (array_from(|c| source[at[c] as usize]), t)
}

/// The flat indices of the 8 voxels around continuous index q, in [`corners`]' order (clamped
/// to the volume), and q's fraction past the first corner per axis: for sampling several
/// volumes on one grid at q.
#[inline]
pub fn corner_indices(q: [f32; 3], dims: [u32; 3]) -> ([u32; 8], [f32; 3]) {
    let (mut ends, mut t) = ([[0; 2]; 3], [0.0; 3]);
    for a in 0..3 {
        (ends[a], t[a]) = axis_corners(q[a], dims[a]);
    }
    (array_from(|c| corner_index(c, ends, dims)), t)
}

/// Along an axis of n voxels: the voxels continuous index q lies between, clamp(⌊q⌋, 0, n − 1)
/// and clamp(⌊q⌋ + 1, 0, n − 1), and q's fraction past the first.
#[inline]
pub fn axis_corners(q: f32, n: u32) -> ([u32; 2], f32) {
    let base = floor(q);
    // ⌊q⌋ clamped to [−1, n − 1] first, so that the + 1 cannot overflow. Wrapping arithmetic
    // here and in corner_index because the checked forms do not vectorise; nothing wraps.
    let top = (n as i32).wrapping_sub(1);
    let lower = (base as i32).clamp(-1, top);
    (
        [lower.max(0) as u32, lower.wrapping_add(1).min(top) as u32],
        q - base,
    )
}

/// Flat index of corner c (x fastest) of the cell between voxels `ends` (per axis: [i0, i1]);
/// they lie inside the volume, whose voxel count fits a u32.
#[inline]
pub fn corner_index(c: usize, ends: [[u32; 2]; 3], dims: [u32; 3]) -> u32 {
    let pick = |a: usize| ends[a][c >> a & 1];
    pick(0).wrapping_add(dims[0].wrapping_mul(pick(1).wrapping_add(dims[1].wrapping_mul(pick(2)))))
}

/// Value and gradient of the trilinear interpolant of corner values `v` ([`corners`]' order)
/// at fraction `t`: [value, d/di, d/dj, d/dk].
#[inline]
pub fn blend_corners(v: [f32; 8], t: [f32; 3]) -> [f32; 4] {
    let [v000, v100, v010, v110, v001, v101, v011, v111] = v;
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

#[cfg(test)]
mod tests {
    use super::floor;

    #[test]
    fn floor_is_libm_floor_for_every_kind_of_f32() {
        let specials = [
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1e-30,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            3e9,
            -3e9,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        // And a sweep of every 4099th bit pattern (normals, subnormals, NaNs).
        let sweep = (0..u32::MAX / 4099).map(|k| f32::from_bits(k * 4099));
        for x in specials.into_iter().chain(sweep) {
            let (got, want) = (floor(x), x.floor());
            assert!(
                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "floor({x:e}) = {got:e}, libm {want:e}"
            );
        }
    }
}
