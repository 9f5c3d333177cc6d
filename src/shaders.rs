//! WGSL sources, compiled into the binary. A kernel's source is its file with the shared
//! helpers prepended; [`locate`] maps a line of the assembled source back to its file.

const COMMON: (&str, &str) = ("common.wgsl", include_str!("../shaders/common.wgsl"));
const SAMPLE: (&str, &str) = ("sample.wgsl", include_str!("../shaders/sample.wgsl"));
const LATTICE_WARP: (&str, &str) = (
    "lattice_warp.wgsl",
    include_str!("../shaders/lattice_warp.wgsl"),
);
const WARP_SAMPLE: (&str, &str) = (
    "warp_sample.wgsl",
    include_str!("../shaders/warp_sample.wgsl"),
);
const RBF_NODES: (&str, &str) = ("rbf_nodes.wgsl", include_str!("../shaders/rbf_nodes.wgsl"));
const GEOMETRY: (&str, &str) = ("geometry.wgsl", include_str!("../shaders/geometry.wgsl"));
const LABELS: (&str, &str) = ("labels.wgsl", include_str!("../shaders/labels.wgsl"));
const BONE_LOOKUP: (&str, &str) = (
    "bone_lookup.wgsl",
    include_str!("../shaders/bone_lookup.wgsl"),
);
const THRESHOLD: (&str, &str) = ("threshold.wgsl", include_str!("../shaders/threshold.wgsl"));
const GAIN: (&str, &str) = ("gain.wgsl", include_str!("../shaders/gain.wgsl"));
const WINDOW: (&str, &str) = ("window.wgsl", include_str!("../shaders/window.wgsl"));
const FADE: (&str, &str) = ("fade.wgsl", include_str!("../shaders/fade.wgsl"));
const SUM_PARTIALS: (&str, &str) = (
    "sum_partials.wgsl",
    include_str!("../shaders/sum_partials.wgsl"),
);

/// Every kernel: its name and the files it is assembled from, in order.
pub const KERNELS: &[(&str, &[(&str, &str)])] = &[
    (
        "resample",
        &[
            COMMON,
            SAMPLE,
            GEOMETRY,
            (
                "sampling/resample.wgsl",
                include_str!("../shaders/sampling/resample.wgsl"),
            ),
        ],
    ),
    (
        "coverage",
        &[
            COMMON,
            GEOMETRY,
            (
                "sampling/coverage.wgsl",
                include_str!("../shaders/sampling/coverage.wgsl"),
            ),
        ],
    ),
    (
        "label_index",
        &[
            COMMON,
            LABELS,
            (
                "labels/label_index.wgsl",
                include_str!("../shaders/labels/label_index.wgsl"),
            ),
        ],
    ),
    (
        "bone_at_source",
        &[
            COMMON,
            SAMPLE,
            GEOMETRY,
            LABELS,
            BONE_LOOKUP,
            (
                "labels/bone_at_source.wgsl",
                include_str!("../shaders/labels/bone_at_source.wgsl"),
            ),
        ],
    ),
    (
        "fold_stats",
        &[
            COMMON,
            THRESHOLD,
            (
                "fold_stats.wgsl",
                include_str!("../shaders/fold_stats.wgsl"),
            ),
        ],
    ),
    (
        "mark_at_most",
        &[
            COMMON,
            THRESHOLD,
            (
                "mark_at_most.wgsl",
                include_str!("../shaders/mark_at_most.wgsl"),
            ),
        ],
    ),
    (
        "edt",
        &[
            COMMON,
            (
                "regions/edt.wgsl",
                include_str!("../shaders/regions/edt.wgsl"),
            ),
        ],
    ),
    (
        "moments",
        &[
            COMMON,
            (
                "regions/moments.wgsl",
                include_str!("../shaders/regions/moments.wgsl"),
            ),
        ],
    ),
    (
        "local_moments",
        &[
            COMMON,
            (
                "local_moments.wgsl",
                include_str!("../shaders/local_moments.wgsl"),
            ),
        ],
    ),
    (
        "lncc",
        &[
            COMMON,
            WINDOW,
            ("lncc.wgsl", include_str!("../shaders/lncc.wgsl")),
        ],
    ),
    (
        "lncc_terms",
        &[
            COMMON,
            WINDOW,
            (
                "lncc_terms.wgsl",
                include_str!("../shaders/lncc_terms.wgsl"),
            ),
        ],
    ),
    (
        "lncc_gradient",
        &[
            COMMON,
            SAMPLE,
            LATTICE_WARP,
            WARP_SAMPLE,
            (
                "lncc_gradient.wgsl",
                include_str!("../shaders/lncc_gradient.wgsl"),
            ),
        ],
    ),
    (
        "dilate",
        &[
            COMMON,
            ("dilate.wgsl", include_str!("../shaders/dilate.wgsl")),
        ],
    ),
    (
        "fold_smooth",
        &[
            COMMON,
            SAMPLE,
            GEOMETRY,
            LABELS,
            BONE_LOOKUP,
            (
                "fold_smooth.wgsl",
                include_str!("../shaders/fold_smooth.wgsl"),
            ),
        ],
    ),
    (
        "jacobian",
        &[
            COMMON,
            ("jacobian.wgsl", include_str!("../shaders/jacobian.wgsl")),
        ],
    ),
    (
        "lattice_splat",
        &[
            COMMON,
            (
                "lattice_splat.wgsl",
                include_str!("../shaders/lattice_splat.wgsl"),
            ),
        ],
    ),
    (
        "pyramid",
        &[
            COMMON,
            (
                "sampling/pyramid.wgsl",
                include_str!("../shaders/sampling/pyramid.wgsl"),
            ),
        ],
    ),
    (
        "warp_image",
        &[
            COMMON,
            SAMPLE,
            LATTICE_WARP,
            WARP_SAMPLE,
            (
                "warp_image.wgsl",
                include_str!("../shaders/warp_image.wgsl"),
            ),
        ],
    ),
    (
        "gain_terms",
        &[
            COMMON,
            GAIN,
            (
                "gain_terms.wgsl",
                include_str!("../shaders/gain_terms.wgsl"),
            ),
        ],
    ),
    (
        "gain_ratio",
        &[
            COMMON,
            GAIN,
            (
                "gain_ratio.wgsl",
                include_str!("../shaders/gain_ratio.wgsl"),
            ),
        ],
    ),
    (
        "gain_apply",
        &[
            COMMON,
            SAMPLE,
            GAIN,
            (
                "gain_apply.wgsl",
                include_str!("../shaders/gain_apply.wgsl"),
            ),
        ],
    ),
    (
        "warp_cost",
        &[
            COMMON,
            SAMPLE,
            LATTICE_WARP,
            WARP_SAMPLE,
            ("warp_cost.wgsl", include_str!("../shaders/warp_cost.wgsl")),
        ],
    ),
    (
        "warp_field",
        &[
            COMMON,
            LATTICE_WARP,
            (
                "warp_field.wgsl",
                include_str!("../shaders/warp_field.wgsl"),
            ),
        ],
    ),
    (
        "compose",
        &[
            COMMON,
            SAMPLE,
            ("compose.wgsl", include_str!("../shaders/compose.wgsl")),
        ],
    ),
    (
        "fade_warp",
        &[
            COMMON,
            FADE,
            ("fade_warp.wgsl", include_str!("../shaders/fade_warp.wgsl")),
        ],
    ),
    (
        "invert_field",
        &[
            COMMON,
            SAMPLE,
            (
                "invert_field.wgsl",
                include_str!("../shaders/invert_field.wgsl"),
            ),
        ],
    ),
    (
        "rbf_lattice",
        &[
            COMMON,
            RBF_NODES,
            (
                "rbf_lattice.wgsl",
                include_str!("../shaders/rbf_lattice.wgsl"),
            ),
        ],
    ),
    (
        "rbf_adjoint",
        &[
            COMMON,
            RBF_NODES,
            (
                "rbf_adjoint.wgsl",
                include_str!("../shaders/rbf_adjoint.wgsl"),
            ),
        ],
    ),
    (
        "lattice_energy",
        &[
            COMMON,
            (
                "lattice_energy.wgsl",
                include_str!("../shaders/lattice_energy.wgsl"),
            ),
        ],
    ),
    (
        "sum_chunks",
        &[
            COMMON,
            (
                "sum_chunks.wgsl",
                include_str!("../shaders/sum_chunks.wgsl"),
            ),
        ],
    ),
    (
        "sum_partials",
        &[
            COMMON,
            ("(f64 partials)", "alias Partial = f64;"),
            SUM_PARTIALS,
        ],
    ),
    (
        "sum_partials_f32",
        &[
            COMMON,
            ("(f32 partials)", "alias Partial = f32;"),
            SUM_PARTIALS,
        ],
    ),
    (
        "rigid_gn",
        &[
            COMMON,
            SAMPLE,
            (
                "rigid/rigid_gn.wgsl",
                include_str!("../shaders/rigid/rigid_gn.wgsl"),
            ),
        ],
    ),
    (
        "rigid_score",
        &[
            COMMON,
            SAMPLE,
            (
                "rigid/rigid_score.wgsl",
                include_str!("../shaders/rigid/rigid_score.wgsl"),
            ),
        ],
    ),
    (
        "skin_blend",
        &[
            COMMON,
            SAMPLE,
            (
                "skinning/skin_blend.wgsl",
                include_str!("../shaders/skinning/skin_blend.wgsl"),
            ),
        ],
    ),
    (
        "skin_weights",
        &[
            COMMON,
            (
                "skinning/skin_weights.wgsl",
                include_str!("../shaders/skinning/skin_weights.wgsl"),
            ),
        ],
    ),
    (
        "ssd_cells",
        &[
            COMMON,
            ("ssd_cells.wgsl", include_str!("../shaders/ssd_cells.wgsl")),
        ],
    ),
    // The dense stage's family (shaders/dense/).
    (
        "gauss_axis",
        &[
            COMMON,
            (
                "dense/gauss_axis.wgsl",
                include_str!("../shaders/dense/gauss_axis.wgsl"),
            ),
        ],
    ),
    (
        "dense_force",
        &[
            COMMON,
            WINDOW,
            (
                "dense/dense_force.wgsl",
                include_str!("../shaders/dense/dense_force.wgsl"),
            ),
        ],
    ),
    (
        "norm_max",
        &[
            COMMON,
            (
                "dense/norm_max.wgsl",
                include_str!("../shaders/dense/norm_max.wgsl"),
            ),
        ],
    ),
    (
        "field_combine",
        &[
            COMMON,
            FADE,
            (
                "dense/field_combine.wgsl",
                include_str!("../shaders/dense/field_combine.wgsl"),
            ),
        ],
    ),
];

fn parts(kernel: &str) -> &'static [(&'static str, &'static str)] {
    KERNELS
        .iter()
        .find(|(name, _)| *name == kernel)
        .map(|(_, parts)| *parts)
        .unwrap_or_else(|| panic!("no kernel named {kernel}"))
}

/// The assembled WGSL of a kernel.
pub fn source(kernel: &str) -> String {
    parts(kernel)
        .iter()
        .map(|(_, text)| *text)
        .collect::<Vec<_>>()
        .join("\n")
}

/// Which file and line (1-based) line `line` (1-based) of the assembled source comes from.
pub fn locate(kernel: &str, line: usize) -> (&'static str, usize) {
    let mut first = 1;
    for (file, text) in parts(kernel) {
        let lines = text.lines().count() + 1; // + the joining newline
        if line < first + lines {
            return (file, line - first + 1);
        }
        first += lines;
    }
    ("?", line)
}
