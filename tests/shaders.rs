//! Every shader parses and validates with naga (no device needed), and every parameter struct
//! has the same size in Rust and WGSL.

use posereg::abi::{
    AdvanceParams, BoneLookupParams, CandidateParams, ComposeParams, DilateParams, EdtParams,
    EnergyParams, FadeParams, GainParams, InvertParams, JacobianParams, LabelParams, ListParams,
    LnccParams, LnccTermsParams, LocalMomentsParams, MomentsParams, PartialsParams, PushParams,
    PyramidParams, RbfGradParams, RbfLatticeParams, RefreshParams, ResampleParams, RigidParams,
    RoundTripParams, ScoreParams, SkinBlendParams, SkinWeightsParams, SplatParams, SsdParams,
    SumParams, SurfaceParams, ThresholdParams,
};
use posereg::shaders::{locate, source, KERNELS};
use std::mem::size_of;

fn parse(kernel: &str) -> naga::Module {
    let src = source(kernel);
    match naga::front::wgsl::parse_str(&src) {
        Ok(m) => m,
        Err(e) => {
            let line = e
                .location(&src)
                .map(|l| l.line_number as usize)
                .unwrap_or(0);
            let (file, file_line) = locate(kernel, line);
            panic!("shaders/{file}:{file_line}: {}", e.emit_to_string(&src));
        }
    }
}

#[test]
fn every_shader_parses_and_validates() {
    assert!(!KERNELS.is_empty());
    for (kernel, _) in KERNELS {
        let module = parse(kernel);
        let mut validator = naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            // The RBF kernels need f64 (shaders/nonrigid/rbf_lattice.wgsl says why); the GPU backend
            // asks the adapter for SHADER_F64.
            naga::valid::Capabilities::FLOAT64,
        );
        if let Err(e) = validator.validate(&module) {
            let src = source(kernel);
            let line = e
                .location(&src)
                .map(|l| l.line_number as usize)
                .unwrap_or(0);
            let (file, file_line) = locate(kernel, line);
            panic!("shaders/{file}:{file_line}: {}", e.emit_to_string(&src));
        }
        assert!(
            module.entry_points.iter().any(|e| e.name == "main"),
            "{kernel} has no entry point main"
        );
    }
}

/// Size in bytes of the struct named `name` in a kernel, via naga's layouter.
fn wgsl_struct_size(kernel: &str, name: &str) -> u32 {
    let module = parse(kernel);
    let (_, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("{kernel} declares no struct {name}"));
    match ty.inner {
        naga::TypeInner::Struct { span, .. } => span,
        _ => panic!("{name} is not a struct"),
    }
}

#[test]
fn abi_structs_match_their_wgsl_twins() {
    use posereg::abi::dense;
    let pairs: [(&str, &str, usize); 48] = [
        ("warp_image", "RbfGradParams", size_of::<RbfGradParams>()),
        ("gain_terms", "GainParams", size_of::<GainParams>()),
        ("gain_ratio", "GainParams", size_of::<GainParams>()),
        ("gain_apply", "GainParams", size_of::<GainParams>()),
        ("warp_cost", "RbfGradParams", size_of::<RbfGradParams>()),
        (
            "rbf_lattice",
            "RbfLatticeParams",
            size_of::<RbfLatticeParams>(),
        ),
        (
            "rbf_adjoint",
            "RbfLatticeParams",
            size_of::<RbfLatticeParams>(),
        ),
        ("lattice_energy", "EnergyParams", size_of::<EnergyParams>()),
        ("sum_chunks", "SumParams", size_of::<SumParams>()),
        ("list_flagged", "ListParams", size_of::<ListParams>()),
        (
            "round_trip_stats",
            "RoundTripParams",
            size_of::<RoundTripParams>(),
        ),
        ("warp_field", "RbfGradParams", size_of::<RbfGradParams>()),
        ("compose", "ComposeParams", size_of::<ComposeParams>()),
        ("fade_warp", "FadeParams", size_of::<FadeParams>()),
        (
            "sum_partials",
            "PartialsParams",
            size_of::<PartialsParams>(),
        ),
        (
            "sum_partials_f32",
            "PartialsParams",
            size_of::<PartialsParams>(),
        ),
        ("lattice_splat", "SplatParams", size_of::<SplatParams>()),
        ("resample", "ResampleParams", size_of::<ResampleParams>()),
        ("coverage", "ResampleParams", size_of::<ResampleParams>()),
        ("label_index", "LabelParams", size_of::<LabelParams>()),
        (
            "region_surface",
            "SurfaceParams",
            size_of::<SurfaceParams>(),
        ),
        (
            "bone_at_source",
            "BoneLookupParams",
            size_of::<BoneLookupParams>(),
        ),
        (
            "fold_stats",
            "ThresholdParams",
            size_of::<ThresholdParams>(),
        ),
        (
            "mark_at_most",
            "ThresholdParams",
            size_of::<ThresholdParams>(),
        ),
        ("dilate", "DilateParams", size_of::<DilateParams>()),
        (
            "fold_candidates",
            "CandidateParams",
            size_of::<CandidateParams>(),
        ),
        ("fold_push", "PushParams", size_of::<PushParams>()),
        ("fold_refresh", "RefreshParams", size_of::<RefreshParams>()),
        ("fold_advance", "AdvanceParams", size_of::<AdvanceParams>()),
        ("edt", "EdtParams", size_of::<EdtParams>()),
        ("moments", "MomentsParams", size_of::<MomentsParams>()),
        (
            "local_moments",
            "LocalMomentsParams",
            size_of::<LocalMomentsParams>(),
        ),
        ("lncc", "LnccParams", size_of::<LnccParams>()),
        (
            "lncc_terms",
            "LnccTermsParams",
            size_of::<LnccTermsParams>(),
        ),
        ("lncc_gradient", "RbfGradParams", size_of::<RbfGradParams>()),
        (
            "fold_smooth",
            "BoneLookupParams",
            size_of::<BoneLookupParams>(),
        ),
        ("jacobian", "JacobianParams", size_of::<JacobianParams>()),
        ("invert_field", "InvertParams", size_of::<InvertParams>()),
        ("ssd_cells", "SsdParams", size_of::<SsdParams>()),
        ("pyramid", "PyramidParams", size_of::<PyramidParams>()),
        ("rigid_gn", "RigidParams", size_of::<RigidParams>()),
        ("rigid_score", "ScoreParams", size_of::<ScoreParams>()),
        (
            "skin_weights",
            "SkinWeightsParams",
            size_of::<SkinWeightsParams>(),
        ),
        (
            "skin_blend",
            "SkinBlendParams",
            size_of::<SkinBlendParams>(),
        ),
        ("gauss_axis", "GaussParams", size_of::<dense::GaussParams>()),
        (
            "dense_force",
            "ForceParams",
            size_of::<dense::ForceParams>(),
        ),
        ("norm_max", "NormParams", size_of::<dense::NormParams>()),
        (
            "field_combine",
            "CombineParams",
            size_of::<dense::CombineParams>(),
        ),
    ];
    assert_eq!(
        pairs.len(),
        KERNELS.len(),
        "a kernel's parameters are missing from this test"
    );
    for (kernel, name, size) in pairs {
        assert_eq!(
            wgsl_struct_size(kernel, name) as usize,
            size,
            "{kernel}: {name}"
        );
        assert_eq!(
            size % 16,
            0,
            "{name}: uniform structs are padded to 16 bytes"
        );
    }
}

#[test]
fn locate_maps_assembled_lines_back_to_files() {
    // A line of the shared geometry.wgsl and one of the kernel's own file.
    let src = source("resample");
    for (marker, want, text) in [
        (
            "struct ResampleParams",
            "geometry.wgsl",
            include_str!("../shaders/geometry.wgsl"),
        ),
        (
            "var<uniform> params: ResampleParams",
            "sampling/resample.wgsl",
            include_str!("../shaders/sampling/resample.wgsl"),
        ),
    ] {
        let n = src.lines().position(|l| l.contains(marker)).unwrap() + 1;
        let (file, line) = locate("resample", n);
        assert_eq!(file, want);
        assert!(text.lines().nth(line - 1).unwrap().contains(marker));
    }
}

#[test]
fn host_bind_group_layouts_match_shader_bindings() {
    assert_eq!(
        posereg::gpu::bindings().count(),
        KERNELS.len(),
        "a kernel has no host layout"
    );
    for (kernel, host) in posereg::gpu::bindings() {
        let module = parse(kernel);
        let mut declared: Vec<(u32, String)> = module
            .global_variables
            .iter()
            .filter_map(|(_, g)| {
                let b = g.binding.as_ref()?;
                assert_eq!(b.group, 0, "{kernel}: only group 0 is used");
                let kind = match g.space {
                    naga::AddressSpace::Uniform => "Uniform",
                    naga::AddressSpace::Storage { access }
                        if access.contains(naga::StorageAccess::STORE) =>
                    {
                        "ReadWrite"
                    }
                    naga::AddressSpace::Storage { .. } => "Read",
                    other => panic!("{kernel}: unexpected address space {other:?}"),
                };
                Some((b.binding, kind.to_string()))
            })
            .collect();
        declared.sort();
        let expected: Vec<(u32, String)> = host
            .iter()
            .enumerate()
            .map(|(i, b)| (i as u32, format!("{b:?}")))
            .collect();
        assert_eq!(
            declared, expected,
            "{kernel}: shader bindings differ from the host layout"
        );
    }
}
