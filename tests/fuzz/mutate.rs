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

/// Byte offsets of NIfTI-1 header fields (sizeof_hdr, dim[0..8], datatype, bitpix, pixdim,
/// vox_offset, scl_slope, scl_inter, xyzt_units, qform/sform codes, quaternion, srow, magic)
/// and their width in bytes.
const NIFTI1_FIELDS: &[(usize, usize)] = &[
    (0, 4), (40, 2), (42, 2), (44, 2), (46, 2), (48, 2), (50, 2), (68, 2), (70, 2), (72, 2),
    (76, 4), (80, 4), (84, 4), (88, 4), (108, 4), (112, 4), (116, 4), (123, 1), (252, 2),
    (254, 2), (256, 4), (260, 4), (264, 4), (268, 4), (280, 4), (284, 4), (296, 4), (312, 4),
    (344, 4),
];

/// Extreme values a header field is set to (little-endian, cut to the field's width).
fn extreme(rng: &mut ChaCha8Rng, width: usize) -> Vec<u8> {
    let f32s = [0.0f32, -1.0, f32::NAN, f32::INFINITY, 1e30, -1e-30, 0.5, 480.0, 1e9];
    let ints: [i64; 9] = [0, -1, 1, 7, 8, 32767, -32768, i32::MAX as i64, 65536];
    if width == 4 && rng.random_bool(0.5) {
        return f32s[rng.random_range(0..f32s.len())].to_le_bytes().to_vec();
    }
    ints[rng.random_range(0..ints.len())].to_le_bytes()[..width].to_vec()
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
            2 if header && out.len() >= 348 => {
                let (at, width) = NIFTI1_FIELDS[rng.random_range(0..NIFTI1_FIELDS.len())];
                let value = extreme(rng, width);
                out[at..at + width].copy_from_slice(&value);
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
            2 => chars[at] = ['"', ',', '[', ']', '{', '}', '=', '\n', '.', '-', '\u{0}', 'é'][rng.random_range(0..12)],
            3 => chars.truncate(at),
            _ => {
                let numbers = ["nan", "inf", "-1", "0", "1e308", "-0", "99999999999999999999", "1e-320", "4294967296"];
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
