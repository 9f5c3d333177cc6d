// sample.wgsl: trilinear interpolation by hand (no sampler, so the CPU twin in
// src/cpu/sample.rs can match it). Prepended to kernels that sample a volume; such a kernel
// defines `fn source_value(index: u32) -> f32` reading its source binding.
//
// Invariants: q is a continuous voxel index of the source. A point is inside when every
// coordinate lies in [-0.5, n - 0.5] (ITK's rule: half a voxel beyond the outer centres);
// neighbours beyond the edge are clamped to it. Outside points get `background`.

fn inside_source(q: vec3<f32>, dims: vec3<u32>) -> bool {
    return all(q >= vec3<f32>(-0.5)) && all(q <= vec3<f32>(dims) - vec3<f32>(0.5));
}

fn trilinear(q: vec3<f32>, dims: vec3<u32>, background: f32) -> f32 {
    if (!inside_source(q, dims)) {
        return background;
    }
    let base = floor(q);
    let t = q - base;
    let top = vec3<i32>(dims) - vec3<i32>(1);
    let i0 = vec3<u32>(clamp(vec3<i32>(base), vec3<i32>(0), top));
    let i1 = vec3<u32>(clamp(vec3<i32>(base) + vec3<i32>(1), vec3<i32>(0), top));
    let v000 = source_value(voxel_index(i0.x, i0.y, i0.z, dims));
    let v100 = source_value(voxel_index(i1.x, i0.y, i0.z, dims));
    let v010 = source_value(voxel_index(i0.x, i1.y, i0.z, dims));
    let v110 = source_value(voxel_index(i1.x, i1.y, i0.z, dims));
    let v001 = source_value(voxel_index(i0.x, i0.y, i1.z, dims));
    let v101 = source_value(voxel_index(i1.x, i0.y, i1.z, dims));
    let v011 = source_value(voxel_index(i0.x, i1.y, i1.z, dims));
    let v111 = source_value(voxel_index(i1.x, i1.y, i1.z, dims));
    // (1 - t) * a + t * b returns a exactly when t == 0: sampling at voxel centres is exact.
    let c00 = (1.0 - t.x) * v000 + t.x * v100;
    let c10 = (1.0 - t.x) * v010 + t.x * v110;
    let c01 = (1.0 - t.x) * v001 + t.x * v101;
    let c11 = (1.0 - t.x) * v011 + t.x * v111;
    let c0 = (1.0 - t.y) * c00 + t.y * c10;
    let c1 = (1.0 - t.y) * c01 + t.y * c11;
    return (1.0 - t.z) * c0 + t.z * c1;
}

// The value of the voxel whose centre is nearest to q (ties round up: floor(q + 0.5)).
fn nearest(q: vec3<f32>, dims: vec3<u32>, background: f32) -> f32 {
    if (!inside_source(q, dims)) {
        return background;
    }
    let top = vec3<i32>(dims) - vec3<i32>(1);
    let i = vec3<u32>(clamp(vec3<i32>(floor(q + vec3<f32>(0.5))), vec3<i32>(0), top));
    return source_value(voxel_index(i.x, i.y, i.z, dims));
}
