//! quicklook.png: one picture to judge a registration by eye. Rows: sagittal, coronal, axial
//! planes through the knee. Columns: target, source (unregistered), warped source,
//! checkerboard of target and warped, |target − warped|. On the warped column the control
//! points near each plane are drawn as in the paper's figures 2–3: blue at the point in the
//! target, red where it takes its intensities from (point + its displacement), a line between.

use crate::adaptive::ControlPoint;
use crate::error::{Error, Result};
use crate::picture::{pixel_size, plane, window, world_bounds, Panel, PLANES};
use crate::volume::Volume;
use image::{Rgb, RgbImage};
use std::path::Path;

/// Checkerboard square (pixels).
const SQUARE: usize = 12;
const GAP: usize = 4;

fn grey(v: f32, (lo, hi): (f32, f32)) -> Rgb<u8> {
    let g = if v.is_finite() {
        ((v - lo) / (hi - lo) * 255.0).clamp(0.0, 255.0) as u8
    } else {
        0
    };
    Rgb([g, g, g])
}

fn put(img: &mut RgbImage, x: i64, y: i64, colour: Rgb<u8>) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, colour);
    }
}

fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), colour: Rgb<u8>) {
    let steps = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
    for k in 0..=steps {
        let t = k as f64 / steps as f64;
        put(
            img,
            (a.0 + t * (b.0 - a.0)).round() as i64,
            (a.1 + t * (b.1 - a.1)).round() as i64,
            colour,
        );
    }
}

fn dot(img: &mut RgbImage, p: (f64, f64), colour: Rgb<u8>) {
    for dy in -1..=1 {
        for dx in -1..=1 {
            put(
                img,
                p.0.round() as i64 + dx,
                p.1.round() as i64 + dy,
                colour,
            );
        }
    }
}

/// Writes the quicklook picture (atomically). All volumes share the target's grid.
pub fn save(
    path: &Path,
    target: &Volume,
    source: &Volume,
    warped: &Volume,
    points: &[ControlPoint],
    centre: [f64; 3],
) -> Result<()> {
    let pixel = pixel_size(target);
    let (lo, hi) = world_bounds(target);
    let rows: Vec<[Panel; 3]> = PLANES
        .iter()
        .map(|&(h, sign, v)| {
            [target, source, warped].map(|vol| plane(vol, centre, h, sign, v, pixel))
        })
        .collect();
    let levels = window(rows.iter().map(|r| &r[0]));
    let width = rows
        .iter()
        .map(|r| 5 * (r[0].width + GAP))
        .max()
        .unwrap_or(1);
    let height: usize = rows.iter().map(|r| r[0].height + GAP).sum();
    let mut img = RgbImage::new(width as u32, height as u32);
    let mut y0 = 0;
    for (row, &(h, sign, v)) in rows.iter().zip(&PLANES) {
        let (w, ht) = (row[0].width, row[0].height);
        for y in 0..ht {
            for x in 0..w {
                let i = y * w + x;
                let (t, s, wv) = (row[0].values[i], row[1].values[i], row[2].values[i]);
                let check = if (x / SQUARE + y / SQUARE).is_multiple_of(2) {
                    t
                } else {
                    wv
                };
                let diff = (t - wv).abs();
                for (col, value) in [t, s, wv, check, diff].into_iter().enumerate() {
                    img.put_pixel(
                        (col * (w + GAP) + x) as u32,
                        (y0 + y) as u32,
                        grey(value, levels),
                    );
                }
            }
        }
        // Control points near this plane, on the warped column.
        let normal = 3 - h - v;
        let to_pixel = |p: [f64; 3]| {
            let col = if sign > 0.0 {
                (p[h] - lo[h]) / pixel
            } else {
                (hi[h] - p[h]) / pixel
            };
            (
                2.0 * (w + GAP) as f64 + col,
                y0 as f64 + (hi[v] - p[v]) / pixel,
            )
        };
        // Only the points within one pixel of the plane: the adaptive stage places hundreds.
        for cp in points
            .iter()
            .filter(|cp| (cp.position[normal] - centre[normal]).abs() <= pixel)
        {
            let from = to_pixel(cp.position);
            let to = to_pixel(std::array::from_fn(|a| cp.position[a] + cp.displacement[a]));
            line(&mut img, from, to, Rgb([255, 210, 0]));
            dot(&mut img, to, Rgb([230, 40, 40]));
            dot(
                &mut img,
                from,
                if cp.pinned {
                    Rgb([40, 200, 60])
                } else {
                    Rgb([60, 120, 255])
                },
            );
        }
        y0 += ht + GAP;
    }
    crate::io::write_atomically(path, |tmp| {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|e| Error::bad_file(path, format!("cannot write PNG ({e})")))
    })
}
