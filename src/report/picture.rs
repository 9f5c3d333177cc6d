//! Pictures for people: three orthogonal planes through a volume, in world orientation
//! (sagittal with anterior left, coronal and axial in radiological convention: the subject's
//! right on the image's left), whatever the voxel order on disk.

use crate::error::{Error, Result};
use crate::sample::trilinear;
use crate::volume::Volume;
use image::{Rgb, RgbImage};
use nalgebra::Vector4;
use std::path::Path;

/// One plane of intensities, row-major, top row first.
pub struct Panel {
    /// Pixels across.
    pub width: usize,
    /// Pixels down.
    pub height: usize,
    /// Intensities (NaN outside the volume).
    pub values: Vec<f32>,
}

/// World bounding box of the grid's voxel centres.
pub(crate) fn world_bounds(volume: &Volume) -> ([f64; 3], [f64; 3]) {
    let d = volume.grid.dims;
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for corner in 0..8 {
        let ijk = [0, 1, 2].map(|a| {
            if corner >> a & 1 == 1 {
                (d[a] - 1) as f64
            } else {
                0.0
            }
        });
        let w = volume.grid.voxel_to_world(ijk);
        for a in 0..3 {
            lo[a] = lo[a].min(w[a]);
            hi[a] = hi[a].max(w[a]);
        }
    }
    (lo, hi)
}

/// The world points of a plane's pixels, row-major, top row first, and how world points map
/// back to pixels.
pub(crate) struct PlanePoints {
    /// Pixels across.
    pub width: usize,
    /// Pixels down.
    pub height: usize,
    /// World RAS mm of each pixel.
    pub points: Vec<[f64; 3]>,
    /// World axes across and down, the direction across, the bounds and the pixel size.
    h: usize,
    h_sign: f64,
    v: usize,
    lo: [f64; 3],
    hi: [f64; 3],
    pixel: f64,
}

impl PlanePoints {
    /// The plane through `centre` over the bounds `(lo, hi)`, spanned by world axes `h` (left
    /// to right of the picture, running in direction `h_sign`) and `v` (top to bottom, running
    /// towards −v: up is +v).
    pub fn new(
        (lo, hi): ([f64; 3], [f64; 3]),
        centre: [f64; 3],
        (h, h_sign, v): (usize, f64, usize),
        pixel: f64,
    ) -> Self {
        let width = ((hi[h] - lo[h]) / pixel).ceil() as usize + 1;
        let height = ((hi[v] - lo[v]) / pixel).ceil() as usize + 1;
        let mut plane = PlanePoints {
            width,
            height,
            points: Vec::with_capacity(width * height),
            h,
            h_sign,
            v,
            lo,
            hi,
            pixel,
        };
        for row in 0..height {
            for col in 0..width {
                let mut w = centre;
                w[h] = match h_sign > 0.0 {
                    true => lo[h] + col as f64 * pixel,
                    false => hi[h] - col as f64 * pixel,
                };
                w[v] = hi[v] - row as f64 * pixel;
                plane.points.push(w);
            }
        }
        plane
    }

    /// The (column, row) of world point `p` projected onto the plane, in pixels.
    pub fn pixel_of(&self, p: [f64; 3]) -> (f64, f64) {
        let col = match self.h_sign > 0.0 {
            true => (p[self.h] - self.lo[self.h]) / self.pixel,
            false => (self.hi[self.h] - p[self.h]) / self.pixel,
        };
        (col, (self.hi[self.v] - p[self.v]) / self.pixel)
    }

    /// The world axis across the plane's normal.
    pub fn normal(&self) -> usize {
        3 - self.h - self.v
    }

    /// `volume` sampled at the plane's points (trilinear, NaN outside).
    pub fn sample(&self, volume: &Volume) -> Panel {
        let to_voxel = volume.grid.world_to_voxel_affine();
        let dims = volume.grid.dims.map(|d| d as u32);
        let values = self
            .points
            .iter()
            .map(|w| {
                let q = to_voxel * Vector4::new(w[0], w[1], w[2], 1.0);
                let q = [q.x as f32, q.y as f32, q.z as f32];
                trilinear(&volume.data, q, dims, f32::NAN)
            })
            .collect();
        Panel {
            width: self.width,
            height: self.height,
            values,
        }
    }
}

/// Sagittal, coronal and axial planes through `centre` (world RAS mm; the middle of the volume
/// when None), pixels of the finest voxel spacing.
pub fn orthogonal_planes(volume: &Volume, centre: Option<[f64; 3]>) -> [Panel; 3] {
    let (lo, hi) = world_bounds(volume);
    let centre = centre.unwrap_or([0, 1, 2].map(|a| (lo[a] + hi[a]) / 2.0));
    let pixel = pixel_size(volume);
    PLANES.map(|axes| PlanePoints::new((lo, hi), centre, axes, pixel).sample(volume))
}

/// The three planes as (horizontal world axis, its direction, vertical world axis): sagittal
/// with anterior (+y) on the left, coronal with the subject's right (+x) on the left, axial with
/// anterior up.
pub const PLANES: [(usize, f64, usize); 3] = [(1, -1.0, 2), (0, -1.0, 2), (0, -1.0, 1)];

/// The finest voxel spacing: the pixel size of every picture.
pub fn pixel_size(volume: &Volume) -> f64 {
    volume.grid.finest_spacing()
}

/// Display window: 0 to the 99.5th percentile of the finite, positive values.
pub fn window<'a>(panels: impl IntoIterator<Item = &'a Panel>) -> (f32, f32) {
    let mut v: Vec<f32> = panels
        .into_iter()
        .flat_map(|p| p.values.iter().copied())
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    if v.is_empty() {
        return (0.0, 1.0);
    }
    let k = ((v.len() - 1) as f64 * 0.995) as usize;
    let (_, hi, _) = v.select_nth_unstable_by(k, f32::total_cmp);
    (0.0, hi.max(f32::MIN_POSITIVE))
}

/// Lays panels side by side (top-aligned, 4-pixel gaps) as grey levels.
pub fn compose(panels: &[Panel], (lo, hi): (f32, f32)) -> RgbImage {
    let gap = 4;
    let width = panels.iter().map(|p| p.width + gap).sum::<usize>() - gap;
    let height = panels.iter().map(|p| p.height).max().unwrap_or(1);
    let mut img = RgbImage::new(width as u32, height as u32);
    let mut x0 = 0;
    for p in panels {
        for row in 0..p.height {
            for col in 0..p.width {
                let v = p.values[row * p.width + col];
                let g = if v.is_finite() {
                    ((v - lo) / (hi - lo) * 255.0).clamp(0.0, 255.0) as u8
                } else {
                    0
                };
                img.put_pixel((x0 + col) as u32, row as u32, Rgb([g, g, g]));
            }
        }
        x0 += p.width + gap;
    }
    img
}

/// Writes the three planes of `volume` through `centre` side by side as a PNG (atomically).
pub fn save_planes_png(path: &Path, volume: &Volume, centre: Option<[f64; 3]>) -> Result<()> {
    let panels = orthogonal_planes(volume, centre);
    let img = compose(&panels, window(&panels));
    crate::io::write_atomically(path, |tmp| {
        img.save_with_format(tmp, image::ImageFormat::Png)
            .map_err(|e| Error::bad_file(path, format!("cannot write PNG ({e})")))
    })
}
