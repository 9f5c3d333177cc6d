// warp_sample.wgsl: the moving image sampled through the lattice warp at one voxel; shared by
// warp_image, warp_cost and lncc_gradient, which declare `params`, `lattice` and
// `sampled_value` (I0). Mirrored in src/cpu/lattice_warp.rs (warped_sample, warped_value_gradient).

// Where voxel (i, j, k) samples I0, in I0's index space: x + R(x), x on I0's voxel
// stride * (i, j, k).
fn warped_position(i: u32, j: u32, k: u32) -> vec3<f32> {
    let r = warp_at(i, j, k);
    return vec3<f32>(vec3<u32>(i, j, k) * params.stride.xyz) + vec3<f32>(
        linear_row(params.mm_to_index[0], r),
        linear_row(params.mm_to_index[1], r),
        linear_row(params.mm_to_index[2], r),
    );
}

// (W, ∂(W − t)²/∂R) at voxel (i, j, k) against the target's value t: W = I0(x + R(x)), the
// gradient 2 (W − t) ∇I0 in world mm; all zero where x + R(x) lies outside I0.
fn warped_sample(i: u32, j: u32, k: u32, t: f32) -> vec4<f32> {
    let q = warped_position(i, j, k);
    if (!inside_source(q, params.moving_dims.xyz)) {
        return vec4<f32>(0.0);
    }
    let vg = trilinear_with_gradient(q, params.moving_dims.xyz);
    let residual = 2.0 * (vg.x - t);
    return vec4<f32>(
        vg.x,
        residual * linear_row(params.gradient_to_world[0], vg.yzw),
        residual * linear_row(params.gradient_to_world[1], vg.yzw),
        residual * linear_row(params.gradient_to_world[2], vg.yzw),
    );
}

// (W, ∇I0(x + R(x))) at voxel (i, j, k), the gradient in world mm; all zero outside I0.
fn warped_value_gradient(i: u32, j: u32, k: u32) -> vec4<f32> {
    let q = warped_position(i, j, k);
    if (!inside_source(q, params.moving_dims.xyz)) {
        return vec4<f32>(0.0);
    }
    let vg = trilinear_with_gradient(q, params.moving_dims.xyz);
    return vec4<f32>(
        vg.x,
        linear_row(params.gradient_to_world[0], vg.yzw),
        linear_row(params.gradient_to_world[1], vg.yzw),
        linear_row(params.gradient_to_world[2], vg.yzw),
    );
}
