//! Fuzzing the readers of every file a user hands posereg — NIfTI images and label maps,
//! displacement fields, bone-transform JSON, point CSV, settings (TOML and JSON) — with the
//! seeded mutation engine of fuzz/mutate.rs over valid files (.hdr/.img pairs through files on
//! disk, the rest in memory). Every case must return Ok or a
//! clear error naming the file: no panic, no case slower than a bound, and peak memory bounded
//! (the readers cap what they allocate by what the file can hold).
//!
//! `scripts/test` runs POSEREG_FUZZ_CASES (default 1000) cases per reader. The long run:
//!
//!     POSEREG_FUZZ_CASES=1000000 cargo test --release --test fuzz -- --nocapture
//!
//! and POSEREG_FUZZ_SEED picks another seed (default 1). A failure prints the seed and the
//! case index, which replay it exactly.

mod common;
#[path = "fuzz/mutate.rs"]
mod mutate;

use common::*;
use mutate::{case_rng, gzip, mutate_bytes, mutate_gzipped, mutate_text};
use posereg::io::config::{options_toml, parse_options};
use posereg::io::field::{field_from_raw, save_field};
use posereg::io::nifti::{
    labels_from_raw, read_raw, read_raw_bytes, volume_from_raw, write_image, DataType,
};
use posereg::io::points::parse_points;
use posereg::io::transform::{BoneTransform, BoneTransforms};
use posereg::pipeline::register::RegisterOptions;
use posereg::volume::Affine;
use rand::Rng;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// No single case may take longer: a reader that loops or decompresses without bound fails.
const CASE_BOUND: Duration = Duration::from_secs(5);
/// Peak resident memory of the whole run: the seeds are a few KB, so what a mutated header
/// promises is capped by the file's size (exactly for plain files, 1032-fold for gzip).
const PEAK_BOUND_MB: u64 = 512;

fn env_number(name: &str, default: u64) -> u64 {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The valid NIfTI files mutated: float32, scaled int16 and uint8 NIfTI-1 written by posereg,
/// and nibabel's NIfTI-2 and extension-bearing files from tests/data (all uncompressed here;
/// the engine gzips them itself).
fn nifti_seeds(dir: &Path) -> Vec<Vec<u8>> {
    let grid = oblique_grid([6, 5, 4]);
    let vol = smooth_volume(&grid, 3);
    let mut seeds = Vec::new();
    for (dtype, slope) in [
        (DataType::F32, 0.0f32),
        (DataType::I16, 0.5),
        (DataType::U8, 0.0),
    ] {
        let path = dir.join(format!("{dtype:?}.nii"));
        write_image(&path, &grid.dims, &grid.affine, &vol.data, dtype, |h| {
            h.scl_slope = slope;
            h.scl_inter = 10.0 * slope;
        })
        .unwrap();
        seeds.push(std::fs::read(&path).unwrap());
    }
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    seeds.push(std::fs::read(data.join("oblique_extension.nii")).unwrap());
    let nifti2 = std::fs::read(data.join("oblique_nifti2.nii.gz")).unwrap();
    seeds.push(gunzip(&nifti2));
    seeds
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(bytes), &mut out).unwrap();
    out
}

fn field_seed(dir: &Path) -> Vec<u8> {
    let grid = oblique_grid([4, 3, 5]);
    let path = dir.join("field.nii.gz");
    save_field(&path, &smooth_field(&grid, 2, 3.0)).unwrap();
    gunzip(&std::fs::read(path).unwrap())
}

fn transform_seed() -> String {
    let mut m = Affine::identity();
    m[(0, 3)] = 2.5;
    let bones = vec![
        BoneTransform::new(2, "femur", &m),
        BoneTransform::new(3, "tibia", &Affine::identity()),
    ];
    serde_json::to_string_pretty(&BoneTransforms::new(bones)).unwrap()
}

/// What one reader does with one mutated file: Ok(accepted) or the error, which must name
/// the file.
type Reader<'a> = Box<dyn Fn(&mut rand_chacha::ChaCha8Rng) -> (String, Result<(), String>) + 'a>;

/// The valid files every reader's cases start from.
struct Seeds {
    nifti: Vec<Vec<u8>>,
    field: Vec<u8>,
    transform: String,
    settings: Vec<(PathBuf, String)>,
    /// nibabel's big-endian .hdr and .img.
    pair: (Vec<u8>, Vec<u8>),
    /// Where the pair reader writes its cases.
    dir: PathBuf,
}

impl Seeds {
    fn new(dir: &Path) -> Self {
        let defaults = RegisterOptions::default();
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
        let read = |name: &str| std::fs::read(data.join(name)).unwrap();
        Seeds {
            nifti: nifti_seeds(dir),
            field: field_seed(dir),
            transform: transform_seed(),
            settings: vec![
                (PathBuf::from("case.toml"), options_toml(&defaults)),
                (
                    PathBuf::from("case.json"),
                    serde_json::to_string_pretty(&defaults).unwrap(),
                ),
            ],
            pair: (read("oblique_pair_be.hdr"), read("oblique_pair_be.img")),
            dir: dir.to_path_buf(),
        }
    }
}

/// A .hdr/.img pair on disk, either half mutated, the data file sometimes gzipped, read from
/// the header's name.
fn read_pair_case(rng: &mut rand_chacha::ChaCha8Rng, seeds: &Seeds) -> Result<(), String> {
    let (header, data) = &seeds.pair;
    let header = match rng.random_bool(0.6) {
        true => mutate_bytes(rng, header, true),
        false => header.clone(),
    };
    let data = match rng.random_bool(0.4) {
        true => mutate_bytes(rng, data, false),
        false => data.clone(),
    };
    let [hdr, img, img_gz] = ["case.hdr", "case.img", "case.img.gz"].map(|n| seeds.dir.join(n));
    let _ = std::fs::remove_file(&img);
    let _ = std::fs::remove_file(&img_gz);
    std::fs::write(&hdr, header).unwrap();
    match rng.random_bool(0.3) {
        true => std::fs::write(&img_gz, gzip(&data)).unwrap(),
        false => std::fs::write(&img, data).unwrap(),
    }
    read_raw(&hdr)
        .and_then(|raw| volume_from_raw(&hdr, raw))
        .map(|_| ())
        .map_err(|e| e.to_string())
}

fn readers(seeds: &Seeds) -> Vec<(&'static str, Reader<'_>)> {
    let name = Path::new("case.nii.gz");
    let (nifti, field, transform, settings) = (
        &seeds.nifti,
        &seeds.field,
        &seeds.transform,
        &seeds.settings,
    );
    let bytes_of = move |rng: &mut rand_chacha::ChaCha8Rng, seed: &[u8]| match rng.random_bool(0.5)
    {
        true => mutate_gzipped(rng, seed),
        false => mutate_bytes(rng, seed, true),
    };
    vec![
        (
            "nifti",
            Box::new(move |rng| {
                let seed = &nifti[rng.random_range(0..nifti.len())];
                let bytes = bytes_of(rng, seed);
                let as_labels = rng.random_bool(0.3);
                let result = read_raw_bytes(name, &bytes).and_then(|raw| match as_labels {
                    true => labels_from_raw(name, raw).map(|_| ()),
                    false => volume_from_raw(name, raw).map(|_| ()),
                });
                ("case.nii.gz".into(), result.map_err(|e| e.to_string()))
            }),
        ),
        (
            "field",
            Box::new(move |rng| {
                let bytes = bytes_of(rng, field);
                let result = read_raw_bytes(name, &bytes)
                    .and_then(|raw| field_from_raw(name, raw))
                    .map(|_| ());
                ("case.nii.gz".into(), result.map_err(|e| e.to_string()))
            }),
        ),
        (
            "transform",
            Box::new(move |rng| {
                let text = mutate_text(rng, transform);
                let result = BoneTransforms::parse(Path::new("case.json"), &text).map(|_| ());
                ("case.json".into(), result.map_err(|e| e.to_string()))
            }),
        ),
        (
            "points",
            Box::new(move |rng| {
                let text = mutate_text(rng, "x,y,z,name\n1.5,2,3,a\n-4,5e1,6,b\n");
                let result = parse_points(Path::new("case.csv"), &text).map(|_| ());
                ("case.csv".into(), result.map_err(|e| e.to_string()))
            }),
        ),
        (
            "settings",
            Box::new(move |rng| {
                let (path, seed) = &settings[rng.random_range(0..settings.len())];
                let text = mutate_text(rng, seed);
                let result = parse_options::<RegisterOptions>(path, &text).map(|_| ());
                (
                    path.display().to_string(),
                    result.map_err(|e| e.to_string()),
                )
            }),
        ),
        (
            "pair",
            Box::new(move |rng| ("case.".into(), read_pair_case(rng, seeds))),
        ),
    ]
}

fn peak_resident_mb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? >> 10)
}

#[test]
fn every_reader_survives_mutated_files() {
    let cases = env_number("POSEREG_FUZZ_CASES", 1000);
    let seed = env_number("POSEREG_FUZZ_SEED", 1);
    let dir = tempfile::tempdir().unwrap();
    let seeds = Seeds::new(dir.path());
    // The seed files, unmutated, must read: the harness itself is sound.
    assert!(read_raw_bytes(Path::new("seed.nii.gz"), &gzip(&seeds.nifti[0])).is_ok());
    for seed in &seeds.nifti {
        assert!(read_raw_bytes(Path::new("seed.nii"), seed).is_ok());
    }
    // Panics are caught and counted; the default hook would print thousands of backtraces.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut failures = Vec::new();
    for (reader_index, (reader, run)) in readers(&seeds).into_iter().enumerate() {
        let (mut accepted, mut slowest) = (0u64, Duration::ZERO);
        for case in 0..cases {
            let mut rng = case_rng(seed, (reader_index as u64) << 40 | case);
            let started = Instant::now();
            let outcome = catch_unwind(AssertUnwindSafe(|| run(&mut rng)));
            let took = started.elapsed();
            slowest = slowest.max(took);
            let problem = match outcome {
                Err(_) => Some("panicked".to_string()),
                Ok(_) if took > CASE_BOUND => Some(format!("took {took:?}")),
                Ok((_, Ok(()))) => {
                    accepted += 1;
                    None
                }
                Ok((file, Err(message))) if !message.contains(&file) => {
                    Some(format!("error does not name the file: {message}"))
                }
                Ok(_) => None,
            };
            if let Some(problem) = problem {
                failures.push(format!("{reader} seed {seed} case {case}: {problem}"));
            }
        }
        println!(
            "{reader}: {cases} cases, {accepted} accepted, {} refused, slowest {slowest:?}",
            cases - accepted
        );
    }
    std::panic::set_hook(hook);
    let peak = peak_resident_mb();
    println!("peak resident memory: {peak:?} MB");
    assert!(
        failures.is_empty(),
        "{} failures, the first: {:#?}",
        failures.len(),
        &failures[..failures.len().min(10)]
    );
    if let Some(peak) = peak {
        assert!(peak <= PEAK_BOUND_MB, "peak resident memory {peak} MB");
    }
}
