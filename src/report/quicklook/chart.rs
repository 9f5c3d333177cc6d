//! series.png: how the joints moved over a series of poses. One row per joint, its rotations
//! (degrees) on the left and its translations (mm) on the right, each quantity a line over the
//! poses (the source first), so a lab sees the whole motion and a pose that does not follow
//! its neighbours at a glance.

use super::draw::font;
use crate::error::{Error, Result};
use ab_glyph::{FontRef, PxScale};
use image::{Rgb, RgbImage};
use imageproc::drawing::{
    draw_filled_circle_mut, draw_hollow_rect_mut, draw_line_segment_mut, draw_text_mut, text_size,
};
use imageproc::rect::Rect;
use std::path::Path;

/// One quantity over the poses (NaN where a pose has no value).
pub struct Curve {
    /// Its name in the legend.
    pub name: String,
    /// One value per pose.
    pub values: Vec<f64>,
}

/// One panel: quantities of one unit.
pub struct Plot {
    /// Above the panel.
    pub title: String,
    /// The y axis' unit.
    pub unit: &'static str,
    /// Its lines.
    pub curves: Vec<Curve>,
}

/// The whole chart: panels two to a row.
pub struct Chart {
    /// Below each pose on the x axis.
    pub poses: Vec<String>,
    /// Row after row, left then right.
    pub plots: Vec<Plot>,
}

const BACKGROUND: Rgb<u8> = Rgb([255, 255, 255]);
const INK: Rgb<u8> = Rgb([30, 30, 30]);
const GRID: Rgb<u8> = Rgb([225, 225, 225]);
const LINES: [Rgb<u8>; 3] = [Rgb([200, 40, 40]), Rgb([30, 140, 60]), Rgb([40, 90, 210])];
const PANEL: (u32, u32) = (520, 300);
/// Room for the y labels (left), the x labels (below), the title (above).
const MARGIN: (u32, u32, u32) = (64, 46, 30);
const GAP: u32 = 24;
const FONT_PX: f32 = 14.0;

/// Writes `chart` as a PNG (atomically).
pub fn save_chart(path: &Path, chart: &Chart) -> Result<()> {
    let font = font()?;
    let rows = chart.plots.len().div_ceil(2) as u32;
    let cell = (MARGIN.0 + PANEL.0 + GAP, MARGIN.2 + PANEL.1 + MARGIN.1);
    let mut img = RgbImage::from_pixel(2 * cell.0 + GAP, rows * cell.1 + GAP, BACKGROUND);
    for (k, plot) in chart.plots.iter().enumerate() {
        let (col, row) = ((k % 2) as u32, (k / 2) as u32);
        let origin = (GAP + col * cell.0 + MARGIN.0, GAP + row * cell.1 + MARGIN.2);
        draw_plot(&mut img, &font, origin, plot, &chart.poses);
    }
    crate::io::write_atomically(path, |tmp| {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|e| Error::bad_file(path, format!("cannot write PNG ({e})")))
    })
}

/// The y range shown: the values' range widened to at least 2 units and padded by a tenth.
fn y_range(plot: &Plot) -> (f64, f64) {
    let values = plot.curves.iter().flat_map(|c| &c.values);
    let finite: Vec<f64> = values.copied().filter(|v| v.is_finite()).collect();
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if finite.is_empty() {
        return (-1.0, 1.0);
    }
    let middle = 0.5 * (lo + hi);
    let half = (0.5 * (hi - lo)).max(1.0) * 1.1;
    (middle - half, middle + half)
}

fn draw_plot(
    img: &mut RgbImage,
    font: &FontRef,
    (x0, y0): (u32, u32),
    plot: &Plot,
    poses: &[String],
) {
    let (w, h) = (PANEL.0 as f32, PANEL.1 as f32);
    let (x0f, y0f) = (x0 as f32, y0 as f32);
    let (lo, hi) = y_range(plot);
    let x_of = |i: usize| x0f + w * (i as f32 + 0.5) / poses.len().max(1) as f32;
    let y_of = |v: f64| y0f + h * ((hi - v) / (hi - lo)) as f32;
    let text = |img: &mut RgbImage, x: f32, y: f32, colour, s: &str| {
        draw_text_mut(
            img,
            colour,
            x as i32,
            y as i32,
            PxScale::from(FONT_PX),
            font,
            s,
        );
    };
    let width = |s: &str| text_size(PxScale::from(FONT_PX), font, s).0 as f32;
    for k in 0..=4 {
        let v = lo + (hi - lo) * k as f64 / 4.0;
        let y = y_of(v);
        draw_line_segment_mut(img, (x0f, y), (x0f + w, y), GRID);
        let label = format!("{v:.1}");
        text(img, x0f - width(&label) - 6.0, y - 8.0, INK, &label);
    }
    for (i, pose) in poses.iter().enumerate() {
        text(img, x_of(i) - 0.5 * width(pose), y0f + h + 6.0, INK, pose);
    }
    let frame = Rect::at(x0 as i32, y0 as i32).of_size(PANEL.0, PANEL.1);
    draw_hollow_rect_mut(img, frame, INK);
    text(
        img,
        x0f,
        y0f - 22.0,
        INK,
        &format!("{} ({})", plot.title, plot.unit),
    );
    for (curve, colour) in plot.curves.iter().zip(LINES.iter().cycle()) {
        let points: Vec<(f32, f32)> = (curve.values.iter().enumerate())
            .filter(|(_, v)| v.is_finite())
            .map(|(i, v)| (x_of(i), y_of(*v)))
            .collect();
        for pair in points.windows(2) {
            draw_line_segment_mut(img, pair[0], pair[1], *colour);
        }
        for p in &points {
            draw_filled_circle_mut(img, (p.0 as i32, p.1 as i32), 3, *colour);
        }
    }
    // The legend on the title's line, right-aligned, clear of the lines.
    let names: Vec<&str> = plot.curves.iter().map(|c| c.name.as_str()).collect();
    let mut legend_x = x0f + w - names.iter().map(|n| width(n) + 16.0).sum::<f32>();
    for (name, colour) in names.iter().zip(LINES.iter().cycle()) {
        text(img, legend_x, y0f - 22.0, *colour, name);
        legend_x += width(name) + 16.0;
    }
}
