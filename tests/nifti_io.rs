//! NIfTI reading and writing: round trips, oblique affines, files written by nibabel, fields in
//! the ITK convention, and bad files.

mod common;

use common::*;
use posereg::io::field::{load_field, save_field};
use posereg::io::nifti::{
    load_labels, load_volume, read_header, read_raw, save_labels, save_volume, write_image,
    AffineSource, DataType, HeaderInfo,
};
use posereg::volume::{Affine, Grid, Image};
use std::path::{Path, PathBuf};

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data")
}

fn expected_json() -> serde_json::Value {
    let text = std::fs::read_to_string(data_dir().join("oblique_nibabel.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn json_affine(v: &serde_json::Value) -> Affine {
    Affine::from_fn(|r, c| v[r][c].as_f64().unwrap())
}

fn assert_affine_close(a: &Affine, b: &Affine, tol: f64) {
    let gap = (a - b).abs().max();
    assert!(gap <= tol, "affines differ by {gap}:\n{a}\n{b}");
}

/// `vol` written to `path` with `customise` applied to its header, and the header read back.
fn written_with(
    path: &Path,
    vol: &posereg::Volume,
    customise: impl FnOnce(&mut nifti::NiftiHeader),
) -> HeaderInfo {
    let g = &vol.grid;
    write_image(
        path,
        &g.dims,
        &g.affine,
        &vol.data,
        DataType::F32,
        customise,
    )
    .unwrap();
    read_header(path).unwrap()
}

#[test]
fn reads_a_file_written_by_nibabel_with_an_oblique_affine() {
    let expected = expected_json();
    let vol = load_volume(&data_dir().join("oblique_nibabel.nii.gz")).unwrap();
    assert_eq!(vol.grid.dims, [5, 6, 7]);
    assert_affine_close(&vol.grid.affine, &json_affine(&expected["affine"]), 1e-6);
    // int16 on disk with slope 0.5 and intercept 10: the scaled values, in file order.
    let values: Vec<f32> = expected["values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() as f32)
        .collect();
    assert_eq!(vol.data, values);
    assert_eq!(
        vol.grid.orientation_code(),
        expected["orientation"].as_str().unwrap()
    );
}

#[test]
fn reads_the_qform_when_there_is_no_sform() {
    let expected = expected_json();
    let path = data_dir().join("oblique_qform_only.nii.gz");
    let info = read_header(&path).unwrap();
    assert_eq!(info.affine_source, AffineSource::Qform);
    assert_affine_close(
        &info.affine,
        &json_affine(&expected["qform_only_affine"]),
        1e-6,
    );
}

#[test]
fn falls_back_to_pixdim_without_either_form() {
    let dir = tempfile::tempdir().unwrap();
    let vol = smooth_volume(&oblique_grid([3, 4, 5]), 4);
    let info = written_with(&dir.path().join("pixdim.nii"), &vol, |h| {
        h.sform_code = 0;
        h.qform_code = 0;
        h.pixdim = [1.0, 0.5, 0.7, 3.0, 1.0, 1.0, 1.0, 1.0];
    });
    assert_eq!(info.affine_source, AffineSource::Pixdim);
    assert_affine_close(
        &info.affine,
        &Affine::from_diagonal(&nalgebra::Vector4::new(0.5, 0.7, 3.0, 1.0)),
        1e-6, // pixdim is f32
    );
}

#[test]
fn oblique_volume_round_trips_with_sform_exact_and_qform_consistent() {
    let dir = tempfile::tempdir().unwrap();
    let grid = oblique_grid([6, 5, 4]);
    let vol = smooth_volume(&grid, 21);
    for name in ["v.nii", "v.nii.gz"] {
        let path = dir.path().join(name);
        save_volume(&path, &vol, DataType::F32).unwrap();
        let back = load_volume(&path).unwrap();
        assert_eq!(back.data, vol.data);
        // The sform stores f32: exact to f32 rounding of each entry.
        assert_affine_close(&back.grid.affine, &grid.affine, 1e-5);
        // A rotation with zooms is represented exactly by the qform too.
        let q = written_with(&dir.path().join(format!("q{name}")), &vol, |h| {
            h.sform_code = 0
        });
        assert_eq!(q.affine_source, AffineSource::Qform);
        assert_affine_close(&q.affine, &grid.affine, 1e-5);
    }
}

#[test]
fn reflected_affine_uses_qfac() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = oblique_grid([2, 2, 2]).affine;
    for r in 0..3 {
        a[(r, 2)] = -a[(r, 2)]; // flip the third axis: determinant < 0
    }
    let grid = Grid::new([3, 4, 5], a).unwrap();
    let path = dir.path().join("flip.nii.gz");
    let info = written_with(&path, &smooth_volume(&grid, 1), |h| h.sform_code = 0);
    assert_eq!(info.header.pixdim[0], -1.0);
    assert_affine_close(&info.affine, &a, 1e-5);
}

#[test]
fn sheared_affine_keeps_sform_exact_and_qform_nearest_rigid() {
    let dir = tempfile::tempdir().unwrap();
    let mut a = Affine::identity();
    a[(0, 1)] = 0.3; // shear: no rotation+zooms reproduces it
    let grid = Grid::new([3, 3, 3], a).unwrap();
    let path = dir.path().join("shear.nii.gz");
    let vol = smooth_volume(&grid, 2);
    save_volume(&path, &vol, DataType::F32).unwrap();
    assert_affine_close(&load_volume(&path).unwrap().grid.affine, &a, 1e-6);
    let q = written_with(&dir.path().join("shear_q.nii.gz"), &vol, |h| {
        h.sform_code = 0
    })
    .affine;
    let r = q.fixed_view::<3, 3>(0, 0);
    let zooms: Vec<f64> = (0..3).map(|c| r.column(c).norm()).collect();
    let rot = nalgebra::Matrix3::from_fn(|i, j| r[(i, j)] / zooms[j]);
    assert_affine_close(
        &(rot.transpose() * rot).fixed_resize::<4, 4>(0.0),
        &nalgebra::Matrix3::identity().fixed_resize::<4, 4>(0.0),
        1e-6,
    );
}

#[test]
fn every_datatype_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let grid = Grid::new([4, 3, 2], Affine::identity()).unwrap();
    let values: Vec<f32> = (0..24).map(|i| (i * 10) as f32).collect();
    let vol = Image::from_data(grid, values.clone()).unwrap();
    for dtype in [
        DataType::U8,
        DataType::I16,
        DataType::U16,
        DataType::I32,
        DataType::F32,
        DataType::F64,
    ] {
        let path = dir.path().join(format!("{dtype:?}.nii.gz"));
        save_volume(&path, &vol, dtype).unwrap();
        let raw = read_raw(&path).unwrap();
        assert_eq!(raw.data, values, "{dtype:?}");
    }
    // Integers saturate instead of wrapping.
    let big = Image::from_data(vol.grid.clone(), vec![300.0; 24]).unwrap();
    let path = dir.path().join("sat.nii");
    save_volume(&path, &big, DataType::U8).unwrap();
    assert!(read_raw(&path).unwrap().data.iter().all(|&v| v == 255.0));
}

#[test]
fn labels_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let grid = oblique_grid([5, 4, 3]);
    let labels: posereg::Labels =
        Image::from_data(grid, (0..60).map(|i| (i % 6) as u16).collect()).unwrap();
    let path = dir.path().join("labels.nii.gz");
    save_labels(&path, &labels).unwrap();
    assert_eq!(load_labels(&path).unwrap().data, labels.data);
    // A non-integer "label" is refused.
    let frac = dir.path().join("frac.nii.gz");
    save_volume(
        &frac,
        &Image::filled(labels.grid.clone(), 1.5f32),
        DataType::F32,
    )
    .unwrap();
    let err = load_labels(&frac).unwrap_err().to_string();
    assert!(
        err.contains("frac.nii.gz") && err.contains("whole number"),
        "{err}"
    );
}

#[test]
fn field_round_trips_and_is_lps_on_disk() {
    let dir = tempfile::tempdir().unwrap();
    let grid = oblique_grid([4, 5, 6]);
    let field = smooth_field(&grid, 3, 5.0);
    let path = dir.path().join("field.nii.gz");
    save_field(&path, &field).unwrap();
    let raw = read_raw(&path).unwrap();
    assert_eq!(raw.info.header.dims, vec![4, 5, 6, 1, 3]);
    assert_eq!(raw.info.header.intent_code, 1007);
    let n = grid.len();
    for i in [0, 7, n - 1] {
        assert_eq!(raw.data[i], -field.data[i][0], "x is negated (R -> L)");
        assert_eq!(raw.data[n + i], -field.data[i][1], "y is negated (A -> P)");
        assert_eq!(raw.data[2 * n + i], field.data[i][2], "z is kept");
    }
    let back = load_field(&path).unwrap();
    assert_eq!(back.data, field.data);
    assert_affine_close(&back.grid.affine, &grid.affine, 1e-5);
}

#[test]
fn bad_files_are_clear_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.nii");
    save_volume(
        &good,
        &smooth_volume(&oblique_grid([8, 8, 8]), 1),
        DataType::F32,
    )
    .unwrap();
    let bytes = std::fs::read(&good).unwrap();

    let truncated = dir.path().join("truncated.nii");
    std::fs::write(&truncated, &bytes[..bytes.len() - 100]).unwrap();
    let short_header = dir.path().join("short.nii");
    std::fs::write(&short_header, &bytes[..100]).unwrap();
    let garbage = dir.path().join("garbage.nii.gz");
    std::fs::write(&garbage, b"this is not a nifti file at all").unwrap();
    let missing = dir.path().join("missing.nii.gz");
    for path in [&truncated, &short_header, &garbage, &missing] {
        let err = load_volume(path).unwrap_err().to_string();
        let name = path.file_name().unwrap().to_string_lossy();
        assert!(
            err.contains(name.as_ref()),
            "error does not name the file: {err}"
        );
    }

    let nan = dir.path().join("nan.nii.gz");
    let mut vol = smooth_volume(&oblique_grid([4, 4, 4]), 1);
    vol.data[5] = f32::NAN;
    save_volume(&nan, &vol, DataType::F32).unwrap();
    let err = load_volume(&nan).unwrap_err().to_string();
    assert!(err.contains("nan.nii.gz") && err.contains("NaN"), "{err}");

    let zero_spacing = dir.path().join("zero.nii");
    write_image(
        &zero_spacing,
        &[3, 3, 3],
        &Affine::identity(),
        &[0.0; 27],
        DataType::F32,
        |h| {
            h.srow_z = [0.0; 4];
        },
    )
    .unwrap();
    let err = load_volume(&zero_spacing).unwrap_err().to_string();
    assert!(
        err.contains("zero.nii") && err.contains("zero axis"),
        "{err}"
    );

    let err = load_field(&good).unwrap_err().to_string();
    assert!(
        err.contains("good.nii") && err.contains("displacement field"),
        "{err}"
    );
}

#[test]
fn failed_writes_leave_no_file_behind() {
    let dir = tempfile::tempdir().unwrap();
    let vol = smooth_volume(&oblique_grid([3, 3, 3]), 1);
    let bad_ext = dir.path().join("out.img");
    assert!(save_volume(&bad_ext, &vol, DataType::F32).is_err());
    let no_dir = dir.path().join("absent/out.nii.gz");
    let err = save_volume(&no_dir, &vol, DataType::F32)
        .unwrap_err()
        .to_string();
    assert!(err.contains("out.nii.gz"), "{err}");
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

#[test]
fn the_shared_real_knee_loads_with_nibabels_affine() {
    // ../shared/data is beside the checkout on development machines; CI may not have it.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/knee-dess/labels.nii.gz");
    if !path.exists() {
        eprintln!("skipped: {} not present", path.display());
        return;
    }
    let labels = load_labels(&path).unwrap();
    assert_eq!(labels.grid.dims, [512, 512, 80]);
    assert_eq!(labels.grid.orientation_code(), "PIR");
    // nibabel 5 prints this affine for the file (nib.load(path).affine).
    let nibabel = Affine::new(
        0.0,
        0.0,
        1.4999975,
        -13.08479977, //
        -0.3125,
        0.0,
        0.0,
        68.3588028, //
        0.0,
        -0.3125,
        0.0,
        79.83719635, //
        0.0,
        0.0,
        0.0,
        1.0,
    );
    assert_affine_close(&labels.grid.affine, &nibabel, 1e-5);
    for code in [2u16, 3, 4, 5] {
        assert!(labels.data.contains(&code), "label {code} missing");
    }
}

#[test]
fn nifti2_big_endian_pairs_and_extensions_read_like_the_plain_file() {
    let expected = expected_json();
    let plain = load_volume(&data_dir().join("oblique_nibabel.nii.gz")).unwrap();
    for name in [
        "oblique_nifti2.nii.gz",
        "oblique_pair_be.hdr",
        "oblique_pair_be.img",
        "oblique_extension.nii",
    ] {
        let vol = load_volume(&data_dir().join(name)).unwrap();
        assert_eq!(vol.data, plain.data, "{name}");
        assert_affine_close(&vol.grid.affine, &json_affine(&expected["affine"]), 1e-6);
    }
    let info = read_header(&data_dir().join("oblique_nifti2.nii.gz")).unwrap();
    assert_eq!(info.header.version, posereg::io::nifti::Version::Nifti2);
    assert!(
        read_header(&data_dir().join("oblique_pair_be.img"))
            .unwrap()
            .header
            .big_endian
    );
    let ext = read_header(&data_dir().join("oblique_extension.nii")).unwrap();
    assert_eq!(
        ext.header.vox_offset,
        expected["extension_vox_offset"].as_u64().unwrap()
    );
    assert!(
        ext.header.vox_offset > 352,
        "the extension moves the voxels"
    );
}

#[test]
fn spatial_units_in_metres_are_read_in_millimetres_as_itk_does() {
    // SimpleITK reads a header with pixdim 0.001 m and xyzt_units = metres as 1 mm spacing.
    let dir = tempfile::tempdir().unwrap();
    let grid = oblique_grid([4, 3, 5]);
    let mut metres = grid.affine;
    for r in 0..3 {
        for c in 0..4 {
            metres[(r, c)] *= 0.001;
        }
    }
    let path = dir.path().join("metres.nii");
    let vol = smooth_volume(&grid, 9);
    write_image(&path, &grid.dims, &metres, &vol.data, DataType::F32, |h| {
        h.xyzt_units = 1
    })
    .unwrap();
    assert_affine_close(&load_volume(&path).unwrap().grid.affine, &grid.affine, 1e-4);
}

/// nibabel's big-endian pair copied to `dir` under `stem` with upper- or lower-case
/// extensions, its .img bytes changed by `patch`; returns the .hdr and .img paths.
fn pair_copy(
    dir: &Path,
    stem: &str,
    upper: bool,
    patch: impl FnOnce(&mut Vec<u8>),
) -> (PathBuf, PathBuf) {
    let (h, i) = if upper {
        ("HDR", "IMG")
    } else {
        ("hdr", "img")
    };
    let hdr = dir.join(format!("{stem}.{h}"));
    let img = dir.join(format!("{stem}.{i}"));
    std::fs::copy(data_dir().join("oblique_pair_be.hdr"), &hdr).unwrap();
    let mut bytes = std::fs::read(data_dir().join("oblique_pair_be.img")).unwrap();
    patch(&mut bytes);
    std::fs::write(&img, bytes).unwrap();
    (hdr, img)
}

#[test]
fn pair_data_is_gzipped_only_by_name_and_partners_keep_their_case() {
    let dir = tempfile::tempdir().unwrap();
    let plain = load_volume(&data_dir().join("oblique_pair_be.img")).unwrap();
    // An uncompressed .img whose first voxel's bytes are gzip's magic 1f 8b.
    let (_, img) = pair_copy(dir.path(), "magic", false, |b| {
        b[..2].copy_from_slice(&[0x1f, 0x8b])
    });
    let vol = load_volume(&img).unwrap();
    let first = i16::from_be_bytes([0x1f, 0x8b]) as f32 * 0.5 + 10.0;
    assert_eq!(vol.data[0], first);
    assert_eq!(vol.data[1..], plain.data[1..]);
    let (hdr, img) = pair_copy(dir.path(), "UPPER", true, |_| {});
    assert_eq!(load_volume(&hdr).unwrap().data, plain.data);
    assert_eq!(load_volume(&img).unwrap().data, plain.data);
}

#[test]
fn a_slope_that_is_zero_or_not_finite_means_unscaled_as_nibabel_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    let grid = oblique_grid([3, 4, 2]);
    let vol = smooth_volume(&grid, 5);
    for slope in [0.0, f32::NAN, f32::INFINITY] {
        let path = dir.path().join("slope.nii");
        write_image(
            &path,
            &grid.dims,
            &grid.affine,
            &vol.data,
            DataType::F32,
            |h| {
                h.scl_slope = slope;
                h.scl_inter = 7.0;
            },
        )
        .unwrap();
        assert_eq!(load_volume(&path).unwrap().data, vol.data, "slope {slope}");
    }
}
