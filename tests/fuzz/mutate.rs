//! A seeded mutation engine over valid files, for the readers' fuzz test: bit flips, bytes set
//! to extremes, header fields set to extreme values, truncations, appended junk, damage inside
//! a gzip stream, and for text: characters deleted, duplicated or replaced and numbers replaced
//! by extremes. Every case is a pure function of (seed, case index), so a failure is replayed
//! from the two numbers the test prints.

use flate2::{write::GzEncoder, Compression};
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::io::Write;

/// The generator of one case.
pub fn case_rng(seed: u64, case: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(case);
    rng
}

/// Byte offsets and widths of NIfTI-1 header fields: sizeof_hdr, dim[0..6], intent_code,
/// datatype, bitpix, pixdim[0..4], vox_offset, scl_slope, scl_inter, xyzt_units, qform and
/// sform codes, quaternion, qoffset_x, srow entries, magic.
#[rustfmt::skip]
const NIFTI1_FIELDS: &[(usize, usize)] = &[
    (0, 4), (40, 2), (42, 2), (44, 2), (46, 2), (48, 2), (50, 2), (68, 2), (70, 2), (72, 2),
    (76, 4), (80, 4), (84, 4), (88, 4), (108, 4), (112, 4), (116, 4), (123, 1), (252, 2),
    (254, 2), (256, 4), (260, 4), (264, 4), (268, 4), (280, 4), (284, 4), (296, 4), (312, 4),
    (344, 4),
];

/// The same fields of a NIfTI-2 header (64-bit dims, offsets and reals, 32-bit codes).
#[rustfmt::skip]
const NIFTI2_FIELDS: &[(usize, usize)] = &[
    (0, 4), (4, 8), (12, 2), (14, 2), (16, 8), (24, 8), (32, 8), (40, 8), (48, 8), (104, 8),
    (112, 8), (120, 8), (128, 8), (168, 8), (176, 8), (184, 8), (344, 4), (348, 4), (352, 8),
    (360, 8), (368, 8), (376, 8), (400, 8), (408, 8), (432, 8), (464, 8), (500, 4), (504, 4),
];

/// Extreme values a header field is set to (little-endian): reals for 4- and 8-byte fields
/// half the time, else integers cut to the field's width.
fn extreme(rng: &mut ChaCha8Rng, width: usize) -> Vec<u8> {
    let reals = [
        0.0f64,
        -1.0,
        f64::NAN,
        f64::INFINITY,
        1e30,
        -1e-30,
        0.5,
        480.0,
        1e9,
        1e300,
    ];
    let ints: [i64; 10] = [
        0,
        -1,
        1,
        7,
        8,
        32767,
        -32768,
        i32::MAX as i64,
        65536,
        i64::MAX,
    ];
    let real = reals[rng.random_range(0..reals.len())];
    match width {
        4 if rng.random_bool(0.5) => (real as f32).to_le_bytes().to_vec(),
        8 if rng.random_bool(0.5) => real.to_le_bytes().to_vec(),
        _ => ints[rng.random_range(0..ints.len())].to_le_bytes()[..width].to_vec(),
    }
}

/// The header field table for `bytes`, by its sizeof_hdr.
fn fields_of(bytes: &[u8]) -> &'static [(usize, usize)] {
    match bytes.get(..4) {
        Some(b) if i32::from_le_bytes(b.try_into().unwrap()) == 540 => NIFTI2_FIELDS,
        _ => NIFTI1_FIELDS,
    }
}

/// One mutation of a binary file; `header` says whether NIfTI-1 field offsets apply.
pub fn mutate_bytes(rng: &mut ChaCha8Rng, bytes: &[u8], header: bool) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let rounds = rng.random_range(1..=3);
    for _ in 0..rounds {
        if out.is_empty() {
            out.push(rng.random());
            continue;
        }
        match rng.random_range(0..6) {
            0 => {
                let bit = rng.random_range(0..out.len() * 8);
                out[bit / 8] ^= 1 << (bit % 8);
            }
            1 => {
                let at = rng.random_range(0..out.len());
                out[at] = [0x00, 0xff, 0x7f, 0x80][rng.random_range(0..4)];
            }
            2 if header => {
                let fields = fields_of(&out);
                let (at, width) = fields[rng.random_range(0..fields.len())];
                let value = extreme(rng, width);
                if at + width <= out.len() {
                    out[at..at + width].copy_from_slice(&value);
                }
            }
            3 => out.truncate(rng.random_range(0..out.len())),
            4 => {
                let extra = rng.random_range(1..64);
                out.extend((0..extra).map(|_| rng.random::<u8>()));
            }
            _ => {
                let at = rng.random_range(0..out.len());
                let len = rng.random_range(1..=16).min(out.len() - at);
                rng.fill_bytes(&mut out[at..at + len]);
            }
        }
    }
    out
}

/// gzip of `bytes` (deterministic: no timestamp).
pub fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = GzEncoder::new(Vec::new(), Compression::fast());
    encoder.write_all(bytes).expect("in memory");
    encoder.finish().expect("in memory")
}

/// A mutated .nii.gz: the header mutated before compressing, or the compressed stream damaged.
pub fn mutate_gzipped(rng: &mut ChaCha8Rng, plain: &[u8]) -> Vec<u8> {
    if rng.random_bool(0.5) {
        gzip(&mutate_bytes(rng, plain, true))
    } else {
        mutate_bytes(rng, &gzip(plain), false)
    }
}

/// One mutation of a text file.
pub fn mutate_text(rng: &mut ChaCha8Rng, text: &str) -> String {
    let mut chars: Vec<char> = text.chars().collect();
    let rounds = rng.random_range(1..=3);
    for _ in 0..rounds {
        if chars.is_empty() {
            chars.push('x');
            continue;
        }
        let at = rng.random_range(0..chars.len());
        match rng.random_range(0..5) {
            0 => {
                let len = rng.random_range(1..=8).min(chars.len() - at);
                chars.drain(at..at + len);
            }
            1 => {
                let len = rng.random_range(1..=8).min(chars.len() - at);
                let copy: Vec<char> = chars[at..at + len].to_vec();
                chars.splice(at..at, copy);
            }
            2 => {
                chars[at] = [
                    '"', ',', '[', ']', '{', '}', '=', '\n', '.', '-', '\u{0}', 'é',
                ][rng.random_range(0..12)]
            }
            3 => chars.truncate(at),
            _ => {
                let numbers = [
                    "nan",
                    "inf",
                    "-1",
                    "0",
                    "1e308",
                    "-0",
                    "99999999999999999999",
                    "1e-320",
                    "4294967296",
                ];
                let word = numbers[rng.random_range(0..numbers.len())];
                // Replace the number (digits, sign, point) around `at`, or insert at `at`.
                let is_num = |c: char| c.is_ascii_digit() || c == '.' || c == '-' || c == 'e';
                let mut end = at;
                while end < chars.len() && is_num(chars[end]) {
                    end += 1;
                }
                chars.splice(at..end, word.chars());
            }
        }
    }
    chars.into_iter().collect()
}
