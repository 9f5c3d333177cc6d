//! Every bad input a user can hand posereg, built here, run through the binary: each must exit
//! 1 (2 for a usage error) within a time bound, without a panic, with a last line that names the
//! offending file or setting and the problem, and leave nothing in the output folder.
//!
//! Categories: NIfTI headers and data (vox_offset, sizeof_hdr, bitpix, datatypes, magic, dims,
//! truncation, trailing data, gzip damage, promises beyond the file or the memory budget,
//! pixdim, sform, qform, scaling, units, NaN voxels, pairs, folders), fields (intent, dims,
//! NaN), label maps, degenerate images (constant, empty, too small for the pyramid), label and
//! bone choices, settings (flags and files: ranges, NaN, unknown keys), output folders, points
//! and transform files, and usage errors.

mod common;

use common::*;
use posereg::io::field::save_field;
use posereg::io::nifti::{save_labels, save_volume, write_image, DataType};
use posereg::volume::{Grid, Image};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// No bad input may take longer to refuse (generous: CI runs tests in parallel on 2 cores).
const BOUND: Duration = Duration::from_secs(60);

/// One bad input: the command line, the exit code, and what the last line must say.
struct Case {
    what: &'static str,
    args: Vec<String>,
    env: Vec<(&'static str, &'static str)>,
    exit: i32,
    /// Substrings the error must hold: the file or setting, and the problem.
    says: Vec<String>,
}

/// The valid inputs every case starts from, in a temporary folder.
struct Inputs {
    dir: tempfile::TempDir,
}

impl Inputs {
    fn new() -> Self {
        let inputs = Inputs {
            dir: tempfile::tempdir().unwrap(),
        };
        // 32 voxels an axis: enough for the default three pyramid levels.
        let grid = oblique_grid([32, 32, 32]);
        save_volume(
            &inputs.path("source.nii.gz"),
            &smooth_volume(&grid, 1),
            DataType::F32,
        )
        .unwrap();
        save_volume(
            &inputs.path("target.nii.gz"),
            &smooth_volume(&grid, 2),
            DataType::F32,
        )
        .unwrap();
        save_labels(
            &inputs.path("labels.nii.gz"),
            &block_labels(&grid, &[(2, 8), (3, 20)], 6),
        )
        .unwrap();
        let small = oblique_grid([6, 5, 4]);
        save_volume(
            &inputs.path("small.nii"),
            &smooth_volume(&small, 3),
            DataType::F32,
        )
        .unwrap();
        // A registration folder: its transform.json and field.nii.gz.
        std::fs::create_dir(inputs.path("reg")).unwrap();
        save_field(
            &inputs.path("reg/field.nii.gz"),
            &smooth_field(&grid, 4, 2.0),
        )
        .unwrap();
        std::fs::write(
            inputs.path("reg/transform.json"),
            r#"{"space": "RAS", "bones": []}"#,
        )
        .unwrap();
        inputs
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn s(&self, name: &str) -> String {
        self.path(name).to_string_lossy().into_owned()
    }

    /// small.nii with `patch` applied to its bytes, saved as `name` (gzipped for .gz names).
    fn patched(&self, name: &str, patch: impl FnOnce(&mut Vec<u8>)) -> String {
        let mut bytes = std::fs::read(self.path("small.nii")).unwrap();
        patch(&mut bytes);
        if name.ends_with(".gz") {
            bytes = gzip(&bytes);
        }
        std::fs::write(self.path(name), bytes).unwrap();
        self.s(name)
    }

    fn register(&self, source: &str, labels: &str, target: &str, extra: &[&str]) -> Vec<String> {
        let mut args: Vec<String> = ["--device", "cpu", "register", "--source"]
            .map(String::from)
            .to_vec();
        args.extend([
            self.s(source),
            "--source-labels".into(),
            self.s(labels),
            "--target".into(),
            self.s(target),
        ]);
        args.extend(["-o".into(), self.s("out")]);
        args.extend(extra.iter().map(|a| a.to_string()));
        args
    }
}

/// Labels: cubes of `side` voxels with the given codes, their corner at (c, c, c).
fn block_labels(grid: &Grid, blocks: &[(u16, usize)], side: usize) -> posereg::Labels {
    let mut labels = Image::filled(grid.clone(), 0u16);
    let d = grid.dims;
    for &(code, corner) in blocks {
        for k in corner..corner + side {
            for j in corner..corner + side {
                for i in corner..corner + side {
                    labels.data[i + d[0] * (j + d[1] * k)] = code;
                }
            }
        }
    }
    labels
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

fn put_i16(bytes: &mut [u8], at: usize, v: i16) {
    bytes[at..at + 2].copy_from_slice(&v.to_le_bytes());
}

fn put_f32(bytes: &mut [u8], at: usize, v: f32) {
    bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// NIfTI-1 header offsets the cases patch.
const DIM: usize = 40;
const DATATYPE: usize = 70;
const BITPIX: usize = 72;
const PIXDIM: usize = 76;
const VOX_OFFSET: usize = 108;
const SCL_SLOPE: usize = 112;
const XYZT_UNITS: usize = 123;
const QFORM_CODE: usize = 252;
const SFORM_CODE: usize = 254;
const QUATERN_B: usize = 256;
const SROW_X: usize = 280;
const MAGIC: usize = 344;

fn no_forms(b: &mut [u8]) {
    put_i16(b, QFORM_CODE, 0);
    put_i16(b, SFORM_CODE, 0);
}

fn info(file: String) -> Vec<String> {
    vec!["info".into(), file]
}

fn case(what: &'static str, args: Vec<String>, says: &[&str]) -> Case {
    Case {
        what,
        args,
        env: Vec::new(),
        exit: 1,
        says: says.iter().map(|s| s.to_string()).collect(),
    }
}

fn nifti_header_cases(x: &Inputs) -> Vec<Case> {
    vec![
        case(
            "vox_offset 0 in a single file",
            info(x.patched("off0.nii", |b| put_f32(b, VOX_OFFSET, 0.0))),
            &["off0.nii", "vox_offset"],
        ),
        case(
            "vox_offset past the end",
            info(x.patched("offend.nii", |b| put_f32(b, VOX_OFFSET, 480.0))),
            &["offend.nii", "truncated"],
        ),
        case(
            "vox_offset not whole",
            info(x.patched("offfrac.nii", |b| put_f32(b, VOX_OFFSET, 352.5))),
            &["offfrac.nii", "vox_offset"],
        ),
        case(
            "vox_offset beyond any file",
            info(x.patched("offhuge.nii", |b| put_f32(b, VOX_OFFSET, 1e30))),
            &["offhuge.nii", "vox_offset"],
        ),
        case(
            "sizeof_hdr 999",
            info(x.patched("size999.nii", |b| {
                b[0..4].copy_from_slice(&999i32.to_le_bytes())
            })),
            &["size999.nii", "sizeof_hdr"],
        ),
        case(
            "bitpix 8 on float32",
            info(x.patched("bitpix8.nii", |b| put_i16(b, BITPIX, 8))),
            &["bitpix8.nii", "bitpix"],
        ),
        case(
            "bitpix 0 on float32",
            info(x.patched("bitpix0.nii.gz", |b| put_i16(b, BITPIX, 0))),
            &["bitpix0.nii.gz", "bitpix"],
        ),
        case(
            "complex64",
            info(x.patched("complex.nii", |b| {
                put_i16(b, DATATYPE, 32);
                put_i16(b, BITPIX, 64);
            })),
            &["complex.nii", "complex64"],
        ),
        case(
            "RGB24",
            info(x.patched("rgb.nii", |b| {
                put_i16(b, DATATYPE, 128);
                put_i16(b, BITPIX, 24);
            })),
            &["rgb.nii", "RGB24"],
        ),
        case(
            "unknown datatype",
            info(x.patched("dt7.nii", |b| put_i16(b, DATATYPE, 7))),
            &["dt7.nii", "not a NIfTI datatype"],
        ),
        case(
            "no magic (Analyze)",
            info(x.patched("analyze.nii", |b| {
                b[MAGIC..MAGIC + 4].copy_from_slice(b"\0\0\0\0")
            })),
            &["analyze.nii", "magic"],
        ),
        case(
            "dim[0] 0",
            info(x.patched("dim00.nii", |b| put_i16(b, DIM, 0))),
            &["dim00.nii", "dim[0]"],
        ),
        case(
            "dim[0] 9",
            info(x.patched("dim09.nii", |b| put_i16(b, DIM, 9))),
            &["dim09.nii", "dim[0]"],
        ),
        case(
            "negative dim",
            info(x.patched("dimneg.nii", |b| put_i16(b, DIM + 4, -3))),
            &["dimneg.nii", "dim[2]"],
        ),
        case(
            "empty dim",
            info(x.patched("dim1zero.nii", |b| put_i16(b, DIM + 2, 0))),
            &["dim1zero.nii", "dim[1]"],
        ),
        case(
            "pixdim 0 without forms",
            info(x.patched("pix0.nii", |b| {
                no_forms(b);
                put_f32(b, PIXDIM + 8, 0.0);
            })),
            &["pix0.nii", "pixdim"],
        ),
        case(
            "pixdim negative without forms",
            info(x.patched("pixneg.nii", |b| {
                no_forms(b);
                put_f32(b, PIXDIM + 4, -1.0);
            })),
            &["pixneg.nii", "pixdim"],
        ),
        case(
            "pixdim NaN under a qform",
            info(x.patched("pixnan.nii", |b| {
                put_i16(b, SFORM_CODE, 0);
                put_f32(b, PIXDIM + 12, f32::NAN);
            })),
            &["pixnan.nii", "pixdim"],
        ),
        case(
            "sform NaN",
            info(x.patched("sformnan.nii", |b| put_f32(b, SROW_X + 4, f32::NAN))),
            &["sformnan.nii", "sform"],
        ),
        case(
            "qform not a rotation",
            info(x.patched("quat.nii", |b| {
                put_i16(b, SFORM_CODE, 0);
                put_f32(b, QUATERN_B, 2.0);
            })),
            &["quat.nii", "qform"],
        ),
        case(
            "scl_inter NaN under a slope",
            info(x.patched("inter.nii", |b| {
                put_f32(b, SCL_SLOPE, 2.0);
                put_f32(b, SCL_SLOPE + 4, f32::NAN);
            })),
            &["inter.nii", "scl_inter"],
        ),
        case(
            "undefined spatial unit",
            info(x.patched("units.nii", |b| b[XYZT_UNITS] = 5)),
            &["units.nii", "unit"],
        ),
    ]
}

fn nifti_data_cases(x: &Inputs) -> Vec<Case> {
    let crc = {
        let mut gz = gzip(&std::fs::read(x.path("small.nii")).unwrap());
        let at = gz.len() - 6; // inside the CRC-32 of the gzip trailer
        gz[at] ^= 0xff;
        std::fs::write(x.path("crc.nii.gz"), gz).unwrap();
        x.s("crc.nii.gz")
    };
    let cut_gz = {
        let gz = gzip(&std::fs::read(x.path("small.nii")).unwrap());
        std::fs::write(x.path("cutgz.nii.gz"), &gz[..gz.len() / 2]).unwrap();
        x.s("cutgz.nii.gz")
    };
    std::fs::create_dir(x.path("folder.nii")).unwrap();
    std::fs::write(
        x.path("text.nii"),
        "this is not an image, it is a text file of some length\n".repeat(8),
    )
    .unwrap();
    std::fs::copy(x.path("small.nii"), x.path("lonely.img")).unwrap();
    let mut budget = case(
        "beyond the memory budget",
        info(x.s("small.nii")),
        &["small.nii", "memory"],
    );
    budget.env = vec![("POSEREG_MEMORY_LIMIT_MB", "0")];
    vec![
        case(
            "truncated voxel data",
            info(x.patched("cut.nii", |b| b.truncate(b.len() - 100))),
            &["cut.nii", "truncated"],
        ),
        case(
            "truncated header",
            info(x.patched("short.nii", |b| b.truncate(100))),
            &["short.nii", "truncated"],
        ),
        case(
            "empty file",
            info(x.patched("empty.nii", |b| b.clear())),
            &["empty.nii", "truncated"],
        ),
        case(
            "data after the promise",
            info(x.patched("long.nii", |b| b.extend([7u8; 64]))),
            &["long.nii", "more voxel data"],
        ),
        case(
            "more data than promised, gzipped",
            info(x.patched("longgz.nii.gz", |b| b.extend([7u8; 64]))),
            &["longgz.nii.gz", "more voxel data"],
        ),
        case("gzip CRC damaged", info(crc), &["crc.nii.gz", "damaged"]),
        case(
            "gzip stream cut",
            info(cut_gz),
            &["cutgz.nii.gz", "damaged"],
        ),
        case(
            "a promise no gzip can hold",
            info(x.patched("bomb.nii.gz", |b| {
                for axis in 1..=3 {
                    put_i16(b, DIM + 2 * axis, 640);
                }
                put_i16(b, DATATYPE, 2);
                put_i16(b, BITPIX, 8);
            })),
            &["bomb.nii.gz", "cannot hold"],
        ),
        case(
            "a folder for a file",
            info(x.s("folder.nii")),
            &["folder.nii", "folder"],
        ),
        case(
            "a text file",
            info(x.s("text.nii")),
            &["text.nii", "not a NIfTI"],
        ),
        case(
            "an .img without its .hdr",
            info(x.s("lonely.img")),
            &["lonely.hdr", "no such file"],
        ),
        budget,
    ]
}

/// Saves a volume or label map on the inputs' 32³ grid (or `grid`) and returns its name.
fn volume(
    x: &Inputs,
    name: &'static str,
    grid: &Grid,
    value: impl Fn(usize) -> f32,
) -> &'static str {
    let vol = Image::from_data(grid.clone(), (0..grid.len()).map(value).collect()).unwrap();
    save_volume(&x.path(name), &vol, DataType::F32).unwrap();
    name
}

fn image_cases(x: &Inputs) -> Vec<Case> {
    let grid = oblique_grid([32, 32, 32]);
    let nan = volume(x, "nan.nii.gz", &grid, |n| {
        if n == 77 {
            f32::NAN
        } else {
            n as f32
        }
    });
    let constant = volume(x, "constant.nii.gz", &grid, |_| 120.0);
    let zero = volume(x, "zero.nii.gz", &grid, |_| 0.0);
    let speck = volume(x, "speck_target.nii.gz", &grid, |n| {
        if n == 5000 {
            100.0
        } else {
            0.0
        }
    });
    let frac = volume(x, "frac_labels.nii.gz", &grid, |n| {
        if n < 500 {
            2.5
        } else {
            0.0
        }
    });
    let tiny = oblique_grid([12, 12, 12]);
    volume(x, "tiny.nii.gz", &tiny, |n| (n % 7) as f32);
    save_labels(
        &x.path("tiny_labels.nii.gz"),
        &block_labels(&tiny, &[(2, 2)], 6),
    )
    .unwrap();
    save_labels(
        &x.path("tissue_only.nii.gz"),
        &Image::filled(grid.clone(), 1u16),
    )
    .unwrap();
    save_labels(
        &x.path("other_grid.nii.gz"),
        &block_labels(&oblique_grid([32, 32, 31]), &[(2, 8)], 6),
    )
    .unwrap();
    save_labels(
        &x.path("speck.nii.gz"),
        &block_labels(&grid, &[(2, 8), (3, 20), (5, 2)], 2),
    )
    .unwrap();
    let mut far = smooth_volume(&grid, 5);
    far.grid.affine[(0, 3)] += 1000.0;
    save_volume(&x.path("far.nii.gz"), &far, DataType::F32).unwrap();
    let four_d = x.path("labels4d.nii.gz");
    write_image(
        &four_d,
        &[32, 32, 32, 2],
        &grid.affine,
        &vec![2.0; 2 * grid.len()],
        DataType::U8,
        |_| {},
    )
    .unwrap();
    let (src, lab, tgt) = ("source.nii.gz", "labels.nii.gz", "target.nii.gz");
    let apply = |image: &str| -> Vec<String> {
        let (transform, target) = (x.s("reg/transform.json"), x.s(tgt));
        let (image, out) = (x.s(image), x.s("applied.nii.gz"));
        let args = [
            "--device", "cpu", "apply", &transform, &image, "--like", &target, "-o", &out,
        ];
        args.iter().map(|a| a.to_string()).collect()
    };
    vec![
        case(
            "NaN voxels in the target",
            x.register(src, lab, nan, &[]),
            &[nan, "NaN"],
        ),
        case(
            "constant target",
            x.register(src, lab, constant, &[]),
            &[constant, "no contrast"],
        ),
        case(
            "all-zero target",
            x.register(src, lab, zero, &[]),
            &[zero, "no contrast"],
        ),
        case(
            "one bright voxel for a target",
            x.register(src, lab, speck, &[]),
            &[speck, "almost empty"],
        ),
        case(
            "constant source",
            x.register(constant, lab, tgt, &[]),
            &[constant, "no contrast"],
        ),
        case(
            "fractional labels",
            x.register(src, frac, tgt, &[]),
            &[frac, "whole number"],
        ),
        case(
            "4-D label map",
            x.register(src, "labels4d.nii.gz", tgt, &[]),
            &["labels4d.nii.gz", "3-D"],
        ),
        case(
            "labels without bones",
            x.register(src, "tissue_only.nii.gz", tgt, &[]),
            &["tissue_only.nii.gz", "no bone labels"],
        ),
        case(
            "labels on another grid",
            x.register(src, "other_grid.nii.gz", tgt, &[]),
            &["other_grid.nii.gz", "differs"],
        ),
        case(
            "a bone of 8 voxels",
            x.register(src, "speck.nii.gz", tgt, &[]),
            &["speck.nii.gz", "too few"],
        ),
        case(
            "too small for the pyramid",
            x.register("tiny.nii.gz", "tiny_labels.nii.gz", "tiny.nii.gz", &[]),
            &["tiny.nii.gz", "pyramid level"],
        ),
        case(
            "scans that do not overlap",
            x.register(src, lab, "far.nii.gz", &[]),
            &["far.nii.gz", "overlap"],
        ),
        case(
            "missing source",
            x.register("absent.nii.gz", lab, tgt, &[]),
            &["absent.nii.gz", "no such file"],
        ),
        case(
            "bone absent",
            x.register(src, lab, tgt, &["--bones", "2,7"]),
            &["labels.nii.gz", "bone 7"],
        ),
        case(
            "fractional labels applied --nearest",
            [apply("frac_labels.nii.gz"), vec!["--nearest".into()]].concat(),
            &["frac_labels.nii.gz", "whole number"],
        ),
        case(
            "an image far from the source",
            apply("far.nii.gz"),
            &["far.nii.gz", "outside the points the field samples"],
        ),
    ]
}

fn settings_cases(x: &Inputs) -> Vec<Case> {
    let config = |name: &'static str, text: &str| {
        std::fs::write(x.path(name), text).unwrap();
        x.s(name)
    };
    let (src, lab, tgt) = ("source.nii.gz", "labels.nii.gz", "target.nii.gz");
    let with = |file: String| x.register(src, lab, tgt, &["--config", &file]);
    vec![
        case(
            "threshold -1 (flag)",
            x.register(src, lab, tgt, &["--threshold=-1"]),
            &["adaptive.threshold", "at least 1"],
        ),
        case(
            "threshold NaN (flag)",
            x.register(src, lab, tgt, &["--threshold", "NaN"]),
            &["adaptive.threshold"],
        ),
        case(
            "iterations 0",
            x.register(src, lab, tgt, &["--iterations", "0"]),
            &["adaptive.iterations", "above 0"],
        ),
        case(
            "similarity per level, too few",
            x.register(src, lab, tgt, &["--similarity", "ssdxlncc"]),
            &["adaptive.similarity", "3 pyramid levels"],
        ),
        case(
            "lncc_radius 0 (file)",
            with(config("radius.toml", "[adaptive]\nlncc_radius = 0\n")),
            &["radius.toml", "lncc_radius"],
        ),
        case(
            "finest_stride 5 (file)",
            with(config("stride.toml", "[adaptive]\nfinest_stride = 5\n")),
            &["stride.toml", "finest_stride"],
        ),
        case(
            "threshold -1 (file)",
            with(config("neg.toml", "[adaptive]\nthreshold = \"-1\"\n")),
            &["neg.toml", "threshold"],
        ),
        case(
            "pins_per_bone 1e8",
            with(config("pins.toml", "pins_per_bone = 100000000\n")),
            &["pins.toml", "pins_per_bone"],
        ),
        case(
            "unknown setting",
            with(config("typo.toml", "[adaptive]\niteratoins = 5\n")),
            &["typo.toml", "unknown field"],
        ),
        case(
            "settings not TOML or JSON",
            with(config("settings.yaml", "adaptive: {}\n")),
            &["settings.yaml", ".toml or .json"],
        ),
        case(
            "values for the wrong level count",
            with(config(
                "levels.json",
                r#"{"adaptive": {"iterations": "3x3"}}"#,
            )),
            &["levels.json", "3 pyramid levels"],
        ),
        case(
            "lattice of a micron",
            with(config("lattice.toml", "[adaptive]\nlattice_mm = 0.001\n")),
            &["lattice.toml", "lattice_mm"],
        ),
        case(
            "iterations negative",
            with(config("negit.toml", "[adaptive]\niterations = -1\n")),
            &["negit.toml", "a list coarse to fine"],
        ),
        case(
            "smoothing NaN",
            with(config("nan.toml", "[adaptive]\nsmoothing = nan\n")),
            &["nan.toml", "smoothing"],
        ),
        case(
            "chain parent absent",
            with(config(
                "chain.toml",
                "[[init.chain]]\nlabel = 2\nname = \"femur\"\nmax_degrees = 0\n\
                 [[init.chain]]\nlabel = 3\nname = \"tibia\"\nparent = 9\nmax_degrees = 160\n",
            )),
            &["chain.toml", "tibia (label 3): parent 9"],
        ),
        case(
            "search backwards",
            with(config(
                "search.toml",
                "[[init.chain]]\nlabel = 2\nname = \"femur\"\nmax_degrees = 0\n\
                 [[init.chain]]\nlabel = 3\nname = \"tibia\"\nparent = 2\n\
                 search_degrees = [90.0, 0.0, 4.0]\nmax_degrees = 160\n",
            )),
            &["search.toml", "search_degrees"],
        ),
        case(
            "settings file not UTF-8",
            with({
                std::fs::write(x.path("latin1.toml"), b"# r\xe9glages\n").unwrap();
                x.s("latin1.toml")
            }),
            &["latin1.toml", "UTF-8"],
        ),
    ]
}

fn field_and_output_cases(x: &Inputs) -> Vec<Case> {
    let grid = oblique_grid([32, 32, 32]);
    let n = grid.len();
    let write = |name: &str, dims: &[usize], intent: i16, value: f32| {
        write_image(
            &x.path(name),
            dims,
            &grid.affine,
            &vec![value; 3 * n],
            DataType::F32,
            |h| h.intent_code = intent,
        )
        .unwrap();
    };
    write("series.nii.gz", &[32, 32, 32, 3], 0, 1.0);
    write("vec4d.nii.gz", &[32, 32, 32, 3], 1007, 1.0);
    write("nanfield.nii.gz", &[32, 32, 32, 1, 3], 1007, f32::NAN);
    std::fs::write(x.path("a_file"), "not a folder").unwrap();
    let resample = |field: &str, like: &str, out: &str| -> Vec<String> {
        let mut args: Vec<String> = ["--device", "cpu", "resample"].map(String::from).to_vec();
        args.extend([
            x.s("source.nii.gz"),
            "--field".into(),
            x.s(field),
            "--like".into(),
            x.s(like),
            "-o".into(),
            x.s(out),
        ]);
        args
    };
    let (src, lab, tgt) = ("source.nii.gz", "labels.nii.gz", "target.nii.gz");
    let mut under_file = x.register(src, lab, tgt, &[]);
    let last = under_file.len() - 1;
    under_file[last] = x.s("a_file/sub");
    let mut onto_file = x.register(src, lab, tgt, &[]);
    onto_file[last] = x.s("a_file");
    vec![
        case(
            "a 4-D time series as a field",
            resample("series.nii.gz", tgt, "o1.nii.gz"),
            &["series.nii.gz", "intent code is 0"],
        ),
        case(
            "a 4-D vector image as a field",
            resample("vec4d.nii.gz", tgt, "o2.nii.gz"),
            &["vec4d.nii.gz", "[x, y, z, 1, 3]"],
        ),
        case(
            "NaN vectors",
            resample("nanfield.nii.gz", tgt, "o3.nii.gz"),
            &["nanfield.nii.gz", "NaN"],
        ),
        case(
            "reference on another grid",
            resample("reg/field.nii.gz", "small.nii", "o4.nii.gz"),
            &["small.nii", "is not the grid"],
        ),
        case(
            "output name not NIfTI",
            resample("reg/field.nii.gz", tgt, "o5.img"),
            &["o5.img", "must end in"],
        ),
        case(
            "output folder is a file",
            onto_file,
            &["a_file", "is a file"],
        ),
        case("output folder under a file", under_file, &["a_file/sub"]),
    ]
}

fn points_cases(x: &Inputs) -> Vec<Case> {
    let csv = |name: &'static str, text: &str| {
        std::fs::write(x.path(name), text).unwrap();
        name
    };
    let apply = |transform: &str, points: &str| -> Vec<String> {
        vec![
            "apply-points".into(),
            x.s(transform),
            x.s(points),
            "-o".into(),
            x.s("mapped.csv"),
        ]
    };
    let centre = oblique_grid([32, 32, 32]).voxel_to_world([16.0; 3]);
    let good = format!("x,y,z\n{},{},{}\n", centre[0], centre[1], centre[2]);
    let pts = csv("good.csv", &good);
    let reg = |name: &str, text: &str| {
        std::fs::create_dir_all(x.path(name)).unwrap();
        std::fs::copy(
            x.path("reg/field.nii.gz"),
            x.path(&format!("{name}/field.nii.gz")),
        )
        .unwrap();
        std::fs::write(x.path(&format!("{name}/transform.json")), text).unwrap();
        format!("{name}/transform.json")
    };
    let garbage = reg("garbage", "{not json");
    let lps = reg("lps", r#"{"space": "LPS", "bones": []}"#);
    let singular = reg(
        "singular",
        r#"{"space": "RAS", "bones": [{"label": 2, "name": "femur", "matrix": [[0,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]}"#,
    );
    vec![
        case(
            "a point a kilometre away",
            apply(
                "reg/transform.json",
                csv("far.csv", &format!("{good}1000000,0,0\n")),
            ),
            &["far.csv", "outside the grid"],
        ),
        case(
            "no z column",
            apply("reg/transform.json", csv("noz.csv", "x,y,w\n1,2,3\n")),
            &["noz.csv", "\"z\""],
        ),
        case(
            "a row short of cells",
            apply(
                "reg/transform.json",
                csv("short.csv", "x,y,z,name\n1,2,3\n"),
            ),
            &["short.csv", "cells"],
        ),
        case(
            "a header and no points",
            apply("reg/transform.json", csv("header.csv", "x,y,z\n")),
            &["header.csv", "no points"],
        ),
        case(
            "a NaN coordinate",
            apply("reg/transform.json", csv("nanpt.csv", "x,y,z\n1,NaN,3\n")),
            &["nanpt.csv", "finite number"],
        ),
        case(
            "transform.json not JSON",
            apply(&garbage, pts),
            &["garbage/transform.json", "not a bone-transform file"],
        ),
        case(
            "transform.json in LPS",
            apply(&lps, pts),
            &["lps/transform.json", "space"],
        ),
        case(
            "a singular bone matrix",
            apply(&singular, pts),
            &["singular/transform.json", "singular"],
        ),
    ]
}

fn usage_cases(x: &Inputs) -> Vec<Case> {
    let usage = |what, args: Vec<String>, says: &[&str]| Case {
        exit: 2,
        ..case(what, args, says)
    };
    let mut missing = x.register("source.nii.gz", "labels.nii.gz", "target.nii.gz", &[]);
    let at = missing.iter().position(|a| a == "--target").unwrap();
    missing.drain(at..at + 2);
    vec![
        usage(
            "an unknown flag",
            x.register(
                "source.nii.gz",
                "labels.nii.gz",
                "target.nii.gz",
                &["--frobnicate"],
            ),
            &["--frobnicate"],
        ),
        usage("a missing input", missing, &["--target"]),
        usage(
            "a threshold that is not a number",
            x.register(
                "source.nii.gz",
                "labels.nii.gz",
                "target.nii.gz",
                &["--threshold", "abc"],
            ),
            &["--threshold", "abc"],
        ),
        usage(
            "a similarity that is not one",
            x.register(
                "source.nii.gz",
                "labels.nii.gz",
                "target.nii.gz",
                &["--similarity", "ssdxmi"],
            ),
            &["--similarity", "'mi'", "ssd or lncc"],
        ),
    ]
}

/// The other verbs: eval, phantom, bend, init --init, apply, resample, bench.
fn verb_cases(x: &Inputs) -> Vec<Case> {
    let arg = |parts: &[&str]| -> Vec<String> {
        let mut args: Vec<String> = vec!["--device".into(), "cpu".into()];
        args.extend(parts.iter().map(|p| p.to_string()));
        args
    };
    let (field, src, lab, tgt) = (
        x.s("reg/field.nii.gz"),
        x.s("source.nii.gz"),
        x.s("labels.nii.gz"),
        x.s("target.nii.gz"),
    );
    let out = x.s("out");
    let init_json = |name: &str, matrix: &str| {
        let text = format!(
            r#"{{"space": "RAS", "bones": [{{"label": 2, "name": "femur", "matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}}, {{"label": 3, "name": "tibia", "matrix": {matrix}}}]}}"#
        );
        std::fs::write(x.path(name), text).unwrap();
        x.s(name)
    };
    let reflection = init_json("reflect.json", "[[-1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]");
    let far = init_json(
        "far_init.json",
        "[[1,0,0,100000],[0,1,0,0],[0,0,1,0],[0,0,0,1]]",
    );
    let init = |given: &str| {
        arg(&[
            "init",
            "--source",
            &src,
            "--source-labels",
            &lab,
            "--target",
            &tgt,
            "-o",
            &out,
            "--init",
            given,
        ])
    };
    let cells = x.path("cells.toml");
    std::fs::write(&cells, "[adaptive]\ncell_levels = [16, 8, 4]\n").unwrap();
    vec![
        case(
            "warped image on another grid",
            arg(&[
                "eval",
                "--field",
                &field,
                "--truth",
                &field,
                "--warped",
                &x.s("small.nii"),
                "--target",
                &tgt,
            ]),
            &["small.nii", "is not on the grid"],
        ),
        case(
            "phantom noise 1e38",
            arg(&["phantom", "--size", "quarter", "--noise=1e38", "-o", &out]),
            &["noise"],
        ),
        case(
            "bend axis with NaN",
            arg(&[
                "bend",
                &src,
                "--labels",
                &lab,
                "--degrees",
                "10",
                "--axis",
                "NaN",
                "0",
                "0",
                "1",
                "0",
                "0",
                "-o",
                &out,
            ]),
            &["--axis", "finite"],
        ),
        case(
            "bend axis outside the image",
            arg(&[
                "bend",
                &src,
                "--labels",
                &lab,
                "--degrees",
                "10",
                "--axis",
                "1e300",
                "0",
                "0",
                "1",
                "0",
                "0",
                "-o",
                &out,
            ]),
            &["--axis", "outside"],
        ),
        case(
            "a reflection to start from",
            init(&reflection),
            &["reflect.json", "not a rotation"],
        ),
        case(
            "a bone moved 100 m",
            init(&far),
            &["far_init.json", "translation"],
        ),
        case(
            "cell levels falling",
            x.register(
                "source.nii.gz",
                "labels.nii.gz",
                "target.nii.gz",
                &["--config", cells.to_str().unwrap()],
            ),
            &["cells.toml", "cell_levels"],
        ),
        case(
            "a bone named twice",
            x.register(
                "source.nii.gz",
                "labels.nii.gz",
                "target.nii.gz",
                &["--bones", "2,2,3"],
            ),
            &["init.bones", "twice"],
        ),
        case(
            "resample background NaN",
            arg(&[
                "resample",
                &src,
                "--field",
                &field,
                "--like",
                &tgt,
                "-o",
                &x.s("r.nii.gz"),
                "--background",
                "NaN",
            ]),
            &["--background"],
        ),
        Case {
            exit: 2,
            ..case(
                "bench of zero runs",
                arg(&["bench", "--runs", "0"]),
                &["--runs"],
            )
        },
    ]
}

/// Damaged and unusual inputs for the verbs' table, beside the valid ones, by name.
fn verb_inputs(x: &Inputs) {
    let grid = oblique_grid([32, 32, 32]);
    let mut nan = smooth_volume(&grid, 5);
    nan.data[100] = f32::NAN;
    save_volume(&x.path("v_nan.nii.gz"), &nan, DataType::F32).unwrap();
    let source = std::fs::read(x.path("source.nii.gz")).unwrap();
    std::fs::write(x.path("v_cut.nii.gz"), &source[..source.len() / 2]).unwrap();
    std::fs::write(x.path("v_text.nii"), "not an image\n").unwrap();
    let small = oblique_grid([6, 5, 4]);
    save_labels(
        &x.path("v_small_labels.nii.gz"),
        &block_labels(&small, &[], 2),
    )
    .unwrap();
    save_labels(&x.path("v_no_bones.nii.gz"), &block_labels(&grid, &[], 6)).unwrap();
    let mut field = smooth_field(&grid, 6, 2.0);
    field.data[7] = [f32::NAN, 0.0, 0.0];
    save_field(&x.path("v_nan_field.nii.gz"), &field).unwrap();
    save_field(
        &x.path("v_small_field.nii.gz"),
        &smooth_field(&small, 7, 1.0),
    )
    .unwrap();
    std::fs::write(x.path("v_broken.json"), "{\"space\": \"RAS\", \"bones\": [").unwrap();
    std::fs::write(x.path("v_nan_points.csv"), "x,y,z\n1,2,3\nNaN,0,0\n").unwrap();
    std::fs::write(x.path("v_two_columns.csv"), "x,y\n1,2\n").unwrap();
    std::fs::write(x.path("v_unknown.toml"), "[adaptive]\nitterations = 3\n").unwrap();
}

/// Each verb but `register` handed a damaged file, a file on another grid, NaN or a setting
/// out of range: all are checked before any work.
fn more_verb_cases(x: &Inputs) -> Vec<Case> {
    verb_inputs(x);
    let (src, lab, tgt, field) = (
        x.s("source.nii.gz"),
        x.s("labels.nii.gz"),
        x.s("target.nii.gz"),
        x.s("reg/field.nii.gz"),
    );
    let (out, transform) = (x.s("out"), x.s("reg/transform.json"));
    let run = |parts: &[&str]| {
        let mut args: Vec<String> = vec!["--device".into(), "cpu".into()];
        args.extend(parts.iter().map(|p| p.to_string()));
        args
    };
    let v = |name: &str| x.s(name);
    let usage = |what, args, says: &[&str]| Case {
        exit: 2,
        ..case(what, args, says)
    };
    let applied = x.s("applied.nii.gz");
    let apply = |t: &str, image: &str, like: &str| {
        run(&["apply", t, image, "--like", like, "-o", &applied])
    };
    let points = |t: &str, csv: &str| run(&["apply-points", t, csv, "-o", &x.s("moved.csv")]);
    let resample = |image: &str, f: &str, like: &str, extra: &[&str]| {
        let args = [
            "resample", image, "--field", f, "--like", like, "-o", &applied,
        ];
        run(&[&args[..], extra].concat())
    };
    let eval = |f: &str, truth: &str, extra: &[&str]| {
        run(&[&["eval", "--field", f, "--truth", truth][..], extra].concat())
    };
    let series = |s: &str, l: &str, last: &str, extra: &[&str]| {
        let args = [
            "series",
            "--source",
            s,
            "--source-labels",
            l,
            "--targets",
            &tgt,
            last,
        ];
        run(&[&args[..], &["-o", &out], extra].concat())
    };
    let pose = |s: &str, l: &str, extra: &[&str]| {
        run(&[&["pose", s, "--labels", l, "-o", &out][..], extra].concat())
    };
    let init = |s: &str, l: &str, t: &str, extra: &[&str]| {
        let args = [
            "init",
            "--source",
            s,
            "--source-labels",
            l,
            "--target",
            t,
            "-o",
            &out,
        ];
        run(&[&args[..], extra].concat())
    };
    let bend = |s: &str, l: &str, degrees: &str| {
        run(&["bend", s, "--labels", l, "--degrees", degrees, "-o", &out])
    };
    let phantom = |extra: &[&str]| run(&[&["phantom", "-o", &out][..], extra].concat());
    vec![
        case(
            "apply: a transform cut short",
            apply(&v("v_broken.json"), &src, &tgt),
            &["v_broken.json", "not a bone-transform file"],
        ),
        case(
            "apply: an image cut short",
            apply(&transform, &v("v_cut.nii.gz"), &tgt),
            &["v_cut.nii.gz"],
        ),
        case(
            "apply: --like not an image",
            apply(&transform, &src, &v("v_text.nii")),
            &["v_text.nii"],
        ),
        case(
            "apply: an image with a NaN voxel",
            apply(&transform, &v("v_nan.nii.gz"), &tgt),
            &["v_nan.nii.gz", "NaN"],
        ),
        case(
            "apply: a missing image",
            apply(&transform, &v("v_none.nii.gz"), &tgt),
            &["v_none.nii.gz"],
        ),
        case(
            "apply-points: a missing transform",
            points(&v("v_none.json"), &v("v_nan_points.csv")),
            &["v_none.json"],
        ),
        case(
            "apply-points: a field for the transform",
            points(&field, &v("v_nan_points.csv")),
            &["field.nii.gz", "give the registration's transform.json"],
        ),
        case(
            "apply-points: a NaN coordinate",
            points(&transform, &v("v_nan_points.csv")),
            &["v_nan_points.csv", "finite"],
        ),
        case(
            "apply-points: two columns",
            points(&transform, &v("v_two_columns.csv")),
            &["v_two_columns.csv"],
        ),
        usage(
            "apply-points: an unknown direction",
            [
                points(&transform, &v("v_nan_points.csv")),
                vec!["--direction".into(), "sideways".into()],
            ]
            .concat(),
            &["--direction"],
        ),
        case(
            "resample: an image cut short",
            resample(&v("v_cut.nii.gz"), &field, &tgt, &[]),
            &["v_cut.nii.gz"],
        ),
        case(
            "resample: an image as the field",
            resample(&src, &tgt, &tgt, &[]),
            &["target.nii.gz", "not a displacement field"],
        ),
        case(
            "resample: a field with NaN vectors",
            resample(&src, &v("v_nan_field.nii.gz"), &tgt, &[]),
            &["v_nan_field.nii.gz", "NaN"],
        ),
        case(
            "resample: --like on another grid than the field",
            resample(&src, &field, &x.s("small.nii"), &[]),
            &["small.nii"],
        ),
        usage(
            "resample: an unknown dtype",
            resample(&src, &field, &tgt, &["--dtype", "f128"]),
            &["--dtype"],
        ),
        case(
            "resample: a source with a NaN voxel",
            resample(&v("v_nan.nii.gz"), &field, &tgt, &[]),
            &["v_nan.nii.gz", "NaN"],
        ),
        case(
            "eval: a truth on another grid",
            eval(&field, &v("v_small_field.nii.gz"), &[]),
            &["v_small_field.nii.gz", "grid"],
        ),
        case(
            "eval: a field with NaN vectors",
            eval(&v("v_nan_field.nii.gz"), &field, &[]),
            &["v_nan_field.nii.gz", "NaN"],
        ),
        case(
            "eval: a mask on another grid",
            eval(&field, &field, &["--mask", &x.s("small.nii")]),
            &["small.nii"],
        ),
        case(
            "eval: a missing field",
            eval(&v("v_none.nii.gz"), &field, &[]),
            &["v_none.nii.gz"],
        ),
        case(
            "series: the last target cut short",
            series(&src, &lab, &v("v_cut.nii.gz"), &[]),
            &["v_cut.nii.gz"],
        ),
        case(
            "series: labels on another grid",
            series(&src, &v("v_small_labels.nii.gz"), &tgt, &[]),
            &["v_small_labels.nii.gz", "grid"],
        ),
        case(
            "series: labels without a bone",
            series(&src, &v("v_no_bones.nii.gz"), &tgt, &[]),
            &["v_no_bones.nii.gz", "bone"],
        ),
        case(
            "series: an unknown setting",
            series(&src, &lab, &tgt, &["--config", &v("v_unknown.toml")]),
            &["v_unknown.toml", "itterations"],
        ),
        case(
            "series: a source with a NaN voxel",
            series(&v("v_nan.nii.gz"), &lab, &tgt, &[]),
            &["v_nan.nii.gz", "NaN"],
        ),
        case(
            "series: the last target with a NaN voxel",
            series(&src, &lab, &v("v_nan.nii.gz"), &[]),
            &["v_nan.nii.gz", "NaN"],
        ),
        case(
            "pose: flexion NaN",
            pose(&src, &lab, &["--flexion", "NaN"]),
            &["flexion is NaN"],
        ),
        case(
            "pose: compression infinite",
            pose(&src, &lab, &["--compression", "inf"]),
            &["compression is inf"],
        ),
        case(
            "pose: labels on another grid",
            pose(&src, &v("v_small_labels.nii.gz"), &[]),
            &["v_small_labels.nii.gz", "grid"],
        ),
        case(
            "pose: a source cut short",
            pose(&v("v_cut.nii.gz"), &lab, &[]),
            &["v_cut.nii.gz"],
        ),
        case(
            "pose: labels without a bone",
            pose(&src, &v("v_no_bones.nii.gz"), &[]),
            &["v_no_bones.nii.gz", "bone"],
        ),
        usage(
            "pose: an unknown side",
            pose(&src, &lab, &["--side", "middle"]),
            &["--side"],
        ),
        case(
            "init: a target cut short",
            init(&src, &lab, &v("v_cut.nii.gz"), &[]),
            &["v_cut.nii.gz"],
        ),
        case(
            "init: a start cut short",
            init(&src, &lab, &tgt, &["--init", &v("v_broken.json")]),
            &["v_broken.json", "not a bone-transform file"],
        ),
        case(
            "init: reach limits falling",
            init(&src, &lab, &tgt, &["--reach", "2,1"]),
            &["reach"],
        ),
        case(
            "init: a source with a NaN voxel",
            init(&v("v_nan.nii.gz"), &lab, &tgt, &[]),
            &["v_nan.nii.gz", "NaN"],
        ),
        case(
            "bend: degrees NaN",
            bend(&src, &lab, "NaN"),
            &["--degrees", "not within"],
        ),
        case(
            "bend: labels without a bone",
            bend(&src, &v("v_no_bones.nii.gz"), "10"),
            &["v_no_bones.nii.gz", "label"],
        ),
        case(
            "bend: labels on another grid",
            bend(&src, &v("v_small_labels.nii.gz"), "10"),
            &["v_small_labels.nii.gz", "grid"],
        ),
        case(
            "bend: a source that is not an image",
            bend(&v("v_text.nii"), &lab, "10"),
            &["v_text.nii"],
        ),
        case(
            "bend: a source with a NaN voxel",
            bend(&v("v_nan.nii.gz"), &lab, "10"),
            &["v_nan.nii.gz", "NaN"],
        ),
        case(
            "phantom: flexion 500",
            phantom(&["--flexion", "500"]),
            &["flexion"],
        ),
        usage(
            "phantom: an unknown size",
            phantom(&["--size", "huge"]),
            &["--size"],
        ),
        case("phantom: bias NaN", phantom(&["--bias", "NaN"]), &["bias"]),
        usage(
            "phantom: a negative seed",
            phantom(&["--seed=-1"]),
            &["--seed"],
        ),
    ]
}

/// Runs one case and returns what is wrong with its outcome, if anything.
fn check(x: &Inputs, case: &Case) -> Option<String> {
    let output = case
        .args
        .iter()
        .position(|a| a == "-o")
        .map(|i| PathBuf::from(&case.args[i + 1]));
    let existed = output.as_ref().is_some_and(|o| o.exists());
    let started = Instant::now();
    let run = Command::new(env!("CARGO_BIN_EXE_posereg"))
        .args(&case.args)
        .envs(case.env.iter().copied())
        .env("XDG_RUNTIME_DIR", x.dir.path())
        .output()
        .expect("the binary runs");
    let took = started.elapsed();
    let stderr = String::from_utf8_lossy(&run.stderr);
    let said = match case.exit {
        1 => stderr.lines().last().unwrap_or("").to_string(),
        _ => stderr.to_string(),
    };
    let problems = [
        (run.status.code() != Some(case.exit))
            .then(|| format!("exit {:?}, expected {}", run.status.code(), case.exit)),
        stderr.contains("panicked").then(|| "panicked".into()),
        (took > BOUND).then(|| format!("took {took:?}")),
        (case.exit == 1 && !said.starts_with("posereg: error:"))
            .then(|| "last line is not the error".into()),
        case.says
            .iter()
            .find(|s| !said.contains(s.as_str()))
            .map(|s| format!("does not say {s:?}")),
        output
            .filter(|o| o.exists() && !existed)
            .map(|o| format!("left {}", o.display())),
    ];
    let found: Vec<String> = problems.into_iter().flatten().collect();
    (!found.is_empty()).then(|| format!("{}: {} — stderr: {stderr}", case.what, found.join("; ")))
}

/// Files a failed run must never leave: temporaries and write probes.
fn stray_files(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir).unwrap().flatten() {
        let path = entry.path();
        if path.is_dir() {
            found.extend(stray_files(&path));
        } else if path
            .file_name()
            .unwrap()
            .to_string_lossy()
            .starts_with(".posereg-")
        {
            found.push(path);
        }
    }
    found
}

#[test]
fn every_bad_input_is_refused_clearly() {
    let x = Inputs::new();
    let cases: Vec<Case> = [
        nifti_header_cases(&x),
        nifti_data_cases(&x),
        image_cases(&x),
        settings_cases(&x),
        field_and_output_cases(&x),
        points_cases(&x),
        usage_cases(&x),
    ]
    .into_iter()
    .flatten()
    .collect();
    run_table(&x, &cases, "bad inputs");
}

/// Runs every case of a table (at least 40) and fails with each case that went wrong; no
/// temporary or probe file may be left anywhere.
fn run_table(x: &Inputs, cases: &[Case], what: &str) {
    assert!(cases.len() >= 40, "{} cases", cases.len());
    let failures: Vec<String> = cases.iter().filter_map(|c| check(x, c)).collect();
    println!("{} {what} refused", cases.len());
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
    assert_eq!(stray_files(x.dir.path()), Vec::<PathBuf>::new());
}

/// Every verb besides `register` checks its inputs before any work (issue 53's table).
#[test]
fn every_verb_refuses_bad_input_clearly() {
    let x = Inputs::new();
    let cases: Vec<Case> = [verb_cases(&x), more_verb_cases(&x)]
        .into_iter()
        .flatten()
        .collect();
    let verbs = [
        "apply",
        "apply-points",
        "resample",
        "eval",
        "series",
        "pose",
        "init",
        "bend",
        "phantom",
    ];
    for verb in verbs {
        assert!(
            cases.iter().any(|c| c.args.iter().any(|a| a == verb)),
            "no case for {verb}"
        );
    }
    run_table(&x, &cases, "bad inputs to the verbs");
}

/// The inputs the table starts from are good: each case fails because of its one bad input.
#[test]
fn the_inputs_the_cases_start_from_are_accepted() {
    let x = Inputs::new();
    for name in ["small.nii", "source.nii.gz", "labels.nii.gz"] {
        let run = posereg(&["info".to_string(), x.s(name)]);
        assert!(
            run.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
    }
    let args = x.register(
        "source.nii.gz",
        "labels.nii.gz",
        "target.nii.gz",
        &["--iterations", "2x0x0", "-q"],
    );
    let run = posereg(&args);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(x.path("out/report.json")).unwrap()).unwrap();
    assert!(
        report["checks"].as_array().is_some_and(|c| c.len() >= 2),
        "{report}"
    );
}

/// Two unrelated smooth images: registering one onto the other cannot raise their correlation,
/// so the correlation check fails; `--strict` makes that exit 1, with every output written.
#[test]
fn strict_turns_a_failed_check_into_an_error_and_keeps_the_outputs() {
    let x = Inputs::new();
    let args = x.register(
        "source.nii.gz",
        "labels.nii.gz",
        "target.nii.gz",
        &["--iterations", "2x0x0", "-q", "--strict"],
    );
    let run = posereg(&args);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("check correlation_improves failed"),
        "{stderr}"
    );
    assert!(
        stderr.lines().last().unwrap().contains("--strict"),
        "{stderr}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(x.path("out/report.json")).unwrap()).unwrap();
    let checks = report["checks"].as_array().unwrap();
    let correlation = checks
        .iter()
        .find(|c| c["name"] == "correlation_improves")
        .unwrap();
    assert_eq!(correlation["passed"], false, "{report}");
    for name in [
        "warped.nii.gz",
        "field.nii.gz",
        "transform.json",
        "jacobian.nii.gz",
    ] {
        assert!(x.path("out").join(name).exists(), "{name}");
    }
}
