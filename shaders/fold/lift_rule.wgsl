// lift_rule.wgsl: whether the fold push lifts a voxel in its pass: det J at or below the
// threshold and the voxel not spared (the first pass spares the voxels whose six stencil
// neighbours all lie in bones, two different ones, whose determinant no push changes; the
// second every bone contact, contacts.wgsl). Prepended after contacts.wgsl to the kernels whose
// `params` have `threshold` and `spared`. Mirrored in src/cpu/fold/fold_candidates.rs (lifts).

// 0 where the pass does not lift voxel v, 1 where it does, 2 where it does although v is a
// bone contact along one axis (the first pass only), so that the host can tell when only
// those are left.
fn lift_code(v: u32, det: f32) -> f32 {
    // The stencil is read only at a voxel at or below the threshold (most are far above it).
    if (det > params.threshold) {
        return 0.0;
    }
    let spans = bone_spans(v);
    if (spans.y || (spans.x && params.spared == 2u)) {
        return 0.0;
    }
    return select(1.0, 2.0, spans.x);
}
