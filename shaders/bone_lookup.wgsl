// bone_lookup.wgsl: which bone a target voxel's source point lands in; prepended (after
// common, sample, geometry and labels) to the kernels that take BoneLookupParams and whose
// sampled_value reads the source label map. Mirrored in src/cpu/labels/bone_at_source.rs (bone_at).

// Keep in sync with abi::BoneLookupParams.
struct BoneLookupParams {
    geometry: ResampleParams,   // target grid → source label grid
    codes: LabelCodes,          // the bones
    limit: f32,                 // largest residual (mm) bone_at_source counts
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// code_index of the source label nearest to target voxel p displaced by u (mm); 0 outside
// the label map.
fn bone_at(p: vec3<f32>, u: vec3<f32>) -> u32 {
    let q = source_index(params.geometry, p, u);
    return code_index(nearest(q, params.geometry.source_dims.xyz, -1.0));
}
