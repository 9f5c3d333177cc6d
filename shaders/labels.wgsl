// labels.wgsl: label codes as the kernels compare them; prepended to the kernels that read a
// label map (label_index, bone_at_source, fold_smooth), whose parameters hold a LabelCodes
// named `codes`. Labels are whole numbers stored as f32 (exact to 2^24); a negative value is
// the background outside the map. Mirrored in src/cpu/labels/bone_at_source.rs.

// Keep in sync with abi::LabelCodes.
struct LabelCodes {
    count: u32,                  // codes in the list
    pad0: u32,
    pad1: u32,
    pad2: u32,
    list: array<vec4<u32>, 2>,   // up to 8 codes, 4 per vector
}

// 1 + the position of `label` in params.codes, 0 when it is none of them.
fn code_index(label: f32) -> u32 {
    if (label < 0.0) {
        return 0u;
    }
    let code = u32(label);
    for (var c = 0u; c < params.codes.count; c = c + 1u) {
        if (params.codes.list[c / 4u][c % 4u] == code) {
            return c + 1u;
        }
    }
    return 0u;
}
