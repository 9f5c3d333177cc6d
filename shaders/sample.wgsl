// sample.wgsl: trilinear interpolation by hand (no sampler, so the CPU twin in
// src/sample.rs can match it). Prepended to kernels that sample a volume; such a kernel
// defines `fn sampled_value(index: u32) -> f32` reading its source binding.
//
// Invariants: q is a continuous voxel index of the source. A point is inside when every
// coordinate lies in [-0.5, n - 0.5] (common.wgsl's inside_source); neighbours beyond the
// edge are clamped to it. Outside points get `background`.

fn trilinear(q: vec3<f32>, dims: vec3<u32>, background: f32) -> f32 {
    if (!inside_source(q, dims)) {
        return background;
    }
    return trilinear_with_gradient(q, dims).x;
}

// The value of the voxel whose centre is nearest to q (ties round up: floor(q + 0.5)).
fn nearest(q: vec3<f32>, dims: vec3<u32>, background: f32) -> f32 {
    if (!inside_source(q, dims)) {
        return background;
    }
    let top = vec3<i32>(dims) - vec3<i32>(1);
    let i = vec3<u32>(clamp(vec3<i32>(floor(q + vec3<f32>(0.5))), vec3<i32>(0), top));
    return sampled_value(voxel_index(i.x, i.y, i.z, dims));
}

// Value and index-space gradient of the trilinear interpolant at q (caller checks
// inside_source): (value, d/di, d/dj, d/dk). The gradient is the interpolant's own derivative
// within q's cell, so it is exact for the function the resampler computes.
fn trilinear_with_gradient(q: vec3<f32>, dims: vec3<u32>) -> vec4<f32> {
    let base = floor(q);
    let t = q - base;
    let top = vec3<i32>(dims) - vec3<i32>(1);
    let i0 = vec3<u32>(clamp(vec3<i32>(base), vec3<i32>(0), top));
    let i1 = vec3<u32>(clamp(vec3<i32>(base) + vec3<i32>(1), vec3<i32>(0), top));
    let v000 = sampled_value(voxel_index(i0.x, i0.y, i0.z, dims));
    let v100 = sampled_value(voxel_index(i1.x, i0.y, i0.z, dims));
    let v010 = sampled_value(voxel_index(i0.x, i1.y, i0.z, dims));
    let v110 = sampled_value(voxel_index(i1.x, i1.y, i0.z, dims));
    let v001 = sampled_value(voxel_index(i0.x, i0.y, i1.z, dims));
    let v101 = sampled_value(voxel_index(i1.x, i0.y, i1.z, dims));
    let v011 = sampled_value(voxel_index(i0.x, i1.y, i1.z, dims));
    let v111 = sampled_value(voxel_index(i1.x, i1.y, i1.z, dims));
    // (1 - t) * a + t * b returns a exactly when t == 0: sampling at voxel centres is exact.
    let c00 = (1.0 - t.x) * v000 + t.x * v100;
    let c10 = (1.0 - t.x) * v010 + t.x * v110;
    let c01 = (1.0 - t.x) * v001 + t.x * v101;
    let c11 = (1.0 - t.x) * v011 + t.x * v111;
    let c0 = (1.0 - t.y) * c00 + t.y * c10;
    let c1 = (1.0 - t.y) * c01 + t.y * c11;
    let value = (1.0 - t.z) * c0 + t.z * c1;
    let dz = c1 - c0;
    let dy = (1.0 - t.z) * (c10 - c00) + t.z * (c11 - c01);
    let e00 = v100 - v000;
    let e10 = v110 - v010;
    let e01 = v101 - v001;
    let e11 = v111 - v011;
    let dx = (1.0 - t.z) * ((1.0 - t.y) * e00 + t.y * e10) + t.z * ((1.0 - t.y) * e01 + t.y * e11);
    return vec4<f32>(value, dx, dy, dz);
}
