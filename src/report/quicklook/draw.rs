//! Drawing the figure: the layout (a margin for titles, cells of one size, a whole-number zoom,
//! a footer), grey levels and colour maps, text in a bundled open font (DejaVu Sans), bone
//! outlines, control points and legends.

use super::panels::PlaneImages;
use super::Figure;
use crate::error::{Error, Result};
use ab_glyph::{FontRef, PxScale};
use image::{Rgb, RgbImage};
use imageproc::drawing::{
    draw_filled_circle_mut, draw_filled_rect_mut, draw_line_segment_mut, draw_text_mut, text_size,
};
use imageproc::rect::Rect;

/// DejaVu Sans (assets/fonts, its licence beside it).
static FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");

/// Around the cells.
const BACKGROUND: Rgb<u8> = Rgb([20, 20, 26]);
/// Inside a cell, beyond the plane's picture (outside the target's grid).
const PAD: Rgb<u8> = Rgb([48, 48, 60]);
const TEXT: Rgb<u8> = Rgb([235, 235, 235]);
/// Stripes where the warped source has no data.
const NO_DATA: [Rgb<u8>; 2] = [Rgb([110, 45, 135]), Rgb([60, 28, 75])];
/// det J ≤ 0.
const FOLDED: Rgb<u8> = Rgb([255, 225, 0]);
const BONE_COLOURS: [Rgb<u8>; 6] = [
    Rgb([255, 170, 0]),
    Rgb([0, 220, 255]),
    Rgb([255, 80, 220]),
    Rgb([90, 230, 90]),
    Rgb([255, 110, 60]),
    Rgb([160, 160, 255]),
];
const POINT: Rgb<u8> = Rgb([60, 120, 255]);
const PINNED: Rgb<u8> = Rgb([40, 200, 60]);
const SAMPLED: Rgb<u8> = Rgb([230, 40, 40]);
const PULL: Rgb<u8> = Rgb([255, 210, 0]);
/// A frame's x (subject's right), y (anterior), z (proximal) axes.
const AXIS_COLOURS: [Rgb<u8>; 3] = [Rgb([240, 60, 60]), Rgb([60, 210, 90]), Rgb([70, 140, 255])];
/// Length of a frame's axes as drawn (mm).
const FRAME_AXIS_MM: f64 = 30.0;
/// Panels are enlarged by a whole factor until a cell is this many pixels across or down.
const MIN_CELL: usize = 240;
const GAP: usize = 6;
const LEFT: usize = 190;
const TOP: usize = 28;
const FOOTER: usize = 116;
/// Checkerboard squares, in plane pixels.
const CHECKER: usize = 12;
const TITLE: f32 = 16.0;
const SMALL: f32 = 13.0;

/// The bundled font, ready to draw with.
pub fn font() -> Result<FontRef<'static>> {
    FontRef::try_from_slice(FONT)
        .map_err(|e| Error::InvalidInput(format!("the bundled font cannot be read: {e}")))
}

/// The picture being drawn.
pub struct Canvas {
    img: RgbImage,
    font: FontRef<'static>,
    zoom: usize,
    cell: (usize, usize),
    rows: usize,
}

impl Canvas {
    /// A canvas for `rows` planes and `columns` panels each.
    pub fn new(rows: &[PlaneImages], columns: usize) -> Result<Self> {
        let font = font()?;
        let w = rows.iter().map(|r| r.plane.width).max().unwrap_or(1);
        let h = rows.iter().map(|r| r.plane.height).max().unwrap_or(1);
        let zoom = MIN_CELL.div_ceil(w.max(h)).max(1);
        let cell = (w * zoom, h * zoom);
        let width = LEFT + columns * (cell.0 + GAP);
        let height = TOP + rows.len() * (cell.1 + GAP) + FOOTER;
        Ok(Canvas {
            img: RgbImage::from_pixel(width as u32, height as u32, BACKGROUND),
            font,
            zoom,
            cell,
            rows: rows.len(),
        })
    }

    /// The picture.
    pub fn into_image(self) -> RgbImage {
        self.img
    }

    /// Top-left corner of the cell of row `r`, column `c`.
    fn origin(&self, r: usize, c: usize) -> (usize, usize) {
        (
            LEFT + c * (self.cell.0 + GAP),
            TOP + r * (self.cell.1 + GAP),
        )
    }

    fn text(&mut self, x: usize, y: usize, scale: f32, colour: Rgb<u8>, text: &str) {
        let (x, y) = (x as i32, y as i32);
        draw_text_mut(
            &mut self.img,
            colour,
            x,
            y,
            PxScale::from(scale),
            &self.font,
            text,
        );
    }

    fn width_of(&self, scale: f32, text: &str) -> usize {
        text_size(PxScale::from(scale), &self.font, text).0 as usize
    }

    /// Column titles above the cells; each row's plane, where it cuts and which way is which.
    pub fn titles(&mut self, columns: &[&str], rows: &[(&str, usize, &str)], centre: [f64; 3]) {
        for (c, title) in columns.iter().enumerate() {
            let (x, _) = self.origin(0, c);
            let centred = x + self.cell.0.saturating_sub(self.width_of(TITLE, title)) / 2;
            self.text(centred, 6, TITLE, TEXT, title);
        }
        for (r, (name, normal, orientation)) in rows.iter().enumerate() {
            let (_, y) = self.origin(r, 0);
            let at = format!("{} = {:.1} mm", ["x", "y", "z"][*normal], centre[*normal]);
            self.text(8, y + self.cell.1 / 2 - 24, TITLE, TEXT, name);
            self.text(8, y + self.cell.1 / 2, SMALL, TEXT, &at);
            self.text(8, y + self.cell.1 / 2 + 18, SMALL, TEXT, orientation);
        }
    }

    /// Fills one plane pixel of cell (r, c) (a zoom × zoom block).
    fn block(&mut self, (x0, y0): (usize, usize), (x, y): (usize, usize), colour: Option<Rgb<u8>>) {
        for dy in 0..self.zoom {
            for dx in 0..self.zoom {
                let (px, py) = (x0 + x * self.zoom + dx, y0 + y * self.zoom + dy);
                let stripe = NO_DATA[((px + py) / 4) % 2];
                self.img
                    .put_pixel(px as u32, py as u32, colour.unwrap_or(stripe));
            }
        }
    }

    /// Row `r`: the six panels of one plane, the bone outlines and the control points.
    pub fn row(&mut self, r: usize, row: &PlaneImages, levels: (f32, f32), figure: &Figure) {
        let (w, h) = (row.plane.width, row.plane.height);
        let offset = (
            (self.cell.0 - w * self.zoom) / 2,
            (self.cell.1 - h * self.zoom) / 2,
        );
        let corners: Vec<(usize, usize)> = (0..6)
            .map(|c| {
                let (x, y) = self.origin(r, c);
                let rect =
                    Rect::at(x as i32, y as i32).of_size(self.cell.0 as u32, self.cell.1 as u32);
                draw_filled_rect_mut(&mut self.img, rect, PAD);
                (x + offset.0, y + offset.1)
            })
            .collect();
        for y in 0..h {
            for x in 0..w {
                for (c, colour) in pixel_colours(row, y * w + x, (x, y), levels)
                    .into_iter()
                    .enumerate()
                {
                    self.block(corners[c], (x, y), colour);
                }
            }
        }
        self.outlines(row, figure, [corners[0], corners[3]]);
        self.control_points(row, figure, corners[2]);
        self.frames(row, figure, corners[0]);
    }

    /// The canvas point of world point `p` on a plane whose panel's corner is `corner`.
    fn to_canvas(&self, row: &PlaneImages, corner: (usize, usize), p: [f64; 3]) -> (f32, f32) {
        let (col, line) = row.plane.pixel_of(p);
        let zoom = self.zoom as f64;
        (
            (corner.0 as f64 + (col + 0.5) * zoom) as f32,
            (corner.1 as f64 + (line + 0.5) * zoom) as f32,
        )
    }

    /// Each frame's axes, [`FRAME_AXIS_MM`] long, projected onto the plane.
    fn frames(&mut self, row: &PlaneImages, figure: &Figure, corner: (usize, usize)) {
        for frame in figure.frames {
            let origin = frame.origin;
            let from = self.to_canvas(row, corner, [origin.x, origin.y, origin.z]);
            for (k, colour) in AXIS_COLOURS.iter().enumerate() {
                let end = origin + frame.axis(k) * FRAME_AXIS_MM;
                let to = self.to_canvas(row, corner, [end.x, end.y, end.z]);
                // Three pixels wide, to stand out over the grey levels.
                for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)] {
                    let shift = |(x, y): (f32, f32)| (x + dx, y + dy);
                    draw_line_segment_mut(&mut self.img, shift(from), shift(to), *colour);
                }
            }
            let at = (from.0 as i32, from.1 as i32);
            draw_filled_circle_mut(&mut self.img, at, 3, TEXT);
        }
    }

    /// The bones' outlines (where a pixel's bone differs from its right or lower neighbour's)
    /// on the panels at `corners`.
    fn outlines(&mut self, row: &PlaneImages, figure: &Figure, corners: [(usize, usize); 2]) {
        let (w, h) = (row.plane.width, row.plane.height);
        let colour_of = |code: u16| {
            let at = figure.bones.iter().position(|(c, _)| *c == code)?;
            Some(BONE_COLOURS[at % BONE_COLOURS.len()])
        };
        for y in 0..h {
            for x in 0..w {
                let here = row.bone[y * w + x];
                let right = (x + 1 < w).then(|| row.bone[y * w + x + 1]);
                let below = (y + 1 < h).then(|| row.bone[(y + 1) * w + x]);
                let edge = [right, below].into_iter().flatten().any(|n| n != here);
                let colour = [Some(here), right, below]
                    .into_iter()
                    .flatten()
                    .find_map(colour_of);
                if let (true, Some(colour)) = (edge, colour) {
                    corners
                        .iter()
                        .for_each(|&c| self.block(c, (x, y), Some(colour)));
                }
            }
        }
    }

    /// Control points within one pixel of the plane: blue (green when pinned on a bone) at the
    /// point, red where it takes its intensities from, a line between.
    fn control_points(&mut self, row: &PlaneImages, figure: &Figure, corner: (usize, usize)) {
        let normal = row.plane.normal();
        let pixel = crate::report::picture::pixel_size(figure.target);
        let near = figure
            .points
            .iter()
            .filter(|p| (p.position[normal] - figure.centre[normal]).abs() <= pixel);
        for p in near {
            let from = self.to_canvas(row, corner, p.position);
            let moved = std::array::from_fn(|a| p.position[a] + p.displacement[a]);
            let to = self.to_canvas(row, corner, moved);
            draw_line_segment_mut(&mut self.img, from, to, PULL);
            let dot = |img: &mut RgbImage, (x, y): (f32, f32), colour| {
                draw_filled_circle_mut(img, (x as i32, y as i32), 3, colour)
            };
            dot(&mut self.img, to, SAMPLED);
            dot(&mut self.img, from, if p.pinned { PINNED } else { POINT });
        }
    }

    /// The summary line, the legends and the Jacobian's colour scale.
    pub fn footer(&mut self, summary: &str, bones: &[(u16, String)]) {
        let y = TOP + self.rows * (self.cell.1 + GAP) + 6;
        self.text(LEFT, y, TITLE, TEXT, summary);
        let mut x = LEFT;
        let legend_y = y + 28;
        for (k, (_, name)) in bones.iter().enumerate() {
            x = self.swatch(x, legend_y, BONE_COLOURS[k % BONE_COLOURS.len()], name);
        }
        x = self.swatch(x, legend_y, NO_DATA[0], "no source data");
        x = self.swatch(x, legend_y, POINT, "control point");
        x = self.swatch(x, legend_y, PINNED, "pinned on a bone");
        self.swatch(x, legend_y, SAMPLED, "where it samples the source");
        self.text(
            LEFT,
            legend_y + 20,
            SMALL,
            TEXT,
            "bone outlines: the source's labels carried by the field, over the target and the checkerboard",
        );
        let mut x = LEFT;
        for (colour, label) in
            AXIS_COLOURS
                .iter()
                .zip(["frame x (right)", "y (anterior)", "z (proximal)"])
        {
            x = self.swatch(x, legend_y + 40, *colour, label);
        }
        self.text(
            x,
            legend_y + 40,
            SMALL,
            TEXT,
            "the bones' kinematic frames on the target, projected",
        );
        self.jacobian_scale(LEFT + 900, legend_y - 2);
    }

    /// A coloured square and its label at (x, y); returns where the next one goes.
    fn swatch(&mut self, x: usize, y: usize, colour: Rgb<u8>, label: &str) -> usize {
        let square = Rect::at(x as i32, y as i32 + 2).of_size(12, 12);
        draw_filled_rect_mut(&mut self.img, square, colour);
        self.text(x + 16, y, SMALL, TEXT, label);
        x + 16 + self.width_of(SMALL, label) + 18
    }

    /// det J from 0 to 2 as a bar, with its ticks, and the colour of folds.
    fn jacobian_scale(&mut self, x: usize, y: usize) {
        let width = 200;
        for k in 0..width {
            let det = 2.0 * (k as f32 + 0.5) / width as f32;
            let bar = Rect::at((x + k) as i32, y as i32).of_size(1, 14);
            draw_filled_rect_mut(&mut self.img, bar, jacobian_colour(det));
        }
        for (det, label) in [(0.0, "0"), (1.0, "1"), (2.0, "2")] {
            let tick = x + (det * (width - 1) as f32 / 2.0) as usize;
            self.text(tick.saturating_sub(3), y + 16, SMALL, TEXT, label);
        }
        self.text(x + width + 10, y, SMALL, TEXT, "det J (2 and up: red)");
        self.swatch(x + width + 10, y + 20, FOLDED, "det J <= 0: folded");
    }
}

/// The colour of plane pixel `i` at (x, y) in each of the six columns; None: stripes for no
/// source data.
fn pixel_colours(
    row: &PlaneImages,
    i: usize,
    (x, y): (usize, usize),
    levels: (f32, f32),
) -> [Option<Rgb<u8>>; 6] {
    let (t, b, wv) = (
        row.target.values[i],
        row.before.values[i],
        row.warped.values[i],
    );
    let seen = |colour: Rgb<u8>| row.covered[i].then_some(colour);
    let warped = seen(grey(wv, levels));
    let checker = match (x / CHECKER + y / CHECKER).is_multiple_of(2) {
        true => Some(grey(t, levels)),
        false => warped,
    };
    [
        Some(grey(t, levels)),
        Some(grey(b, levels)),
        warped,
        checker,
        seen(grey((t - wv).abs(), levels)),
        Some(jacobian_colour(row.jacobian.values[i])),
    ]
    .map(|c| c.map(|c| if t.is_nan() { PAD } else { c }))
}

/// Grey level of `v` in the window; the cell's padding outside the volume (NaN).
fn grey(v: f32, (lo, hi): (f32, f32)) -> Rgb<u8> {
    if !v.is_finite() {
        return PAD;
    }
    let g = ((v - lo) / (hi - lo) * 255.0).clamp(0.0, 255.0) as u8;
    Rgb([g, g, g])
}

/// det J: blue (0) through white (1) to red (2 and up); yellow at or below 0.
fn jacobian_colour(det: f32) -> Rgb<u8> {
    let mix = |a: [f32; 3], b: [f32; 3], t: f32| {
        Rgb(std::array::from_fn(|k| (a[k] + t * (b[k] - a[k])) as u8))
    };
    let (blue, white, red) = ([40.0, 90.0, 230.0], [255.0; 3], [220.0, 50.0, 40.0]);
    match det {
        d if d.is_nan() => PAD,
        d if d <= 0.0 => FOLDED,
        d if d < 1.0 => mix(blue, white, d),
        d => mix(white, red, (d - 1.0).min(1.0)),
    }
}
