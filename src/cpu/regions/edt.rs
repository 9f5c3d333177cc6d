//! CPU twin of shaders/regions/edt.wgsl: the lines in parallel, each read once into a buffer (the
//! shader reads a sample each time its envelope needs it; the values are the same).

use crate::abi::{EdtParams, EDT_FROM_EACH_REGION, EDT_FROM_STACK};
use crate::cpu::common::{dims3, voxel_index};
use crate::sample::floor;
use rayon::prelude::*;

/// No sample along the line yet (the shader's FAR).
const FAR: f32 = 3.0e38;

/// One pass's lines: where their samples are and what the pass reads.
struct Lines<'a> {
    params: &'a EdtParams,
    input: &'a [f32],
    /// Voxels of one volume of the stack.
    voxels: usize,
}

impl Lines<'_> {
    /// Voxel (line position q) of line (a, b) in the volume's flat index.
    fn voxel_of(&self, q: u32, a: u32, b: u32) -> usize {
        let c = match self.params.axis {
            0 => [q, a, b],
            1 => [a, q, b],
            _ => [a, b, q],
        };
        voxel_index(c[0], c[1], c[2], dims3(self.params.dims)) as usize
    }

    /// The squared distance so far at line position q of line (a, b) of volume s.
    fn sample(&self, q: u32, (a, b, s): (u32, u32, u32)) -> f32 {
        let v = self.voxel_of(q, a, b);
        if self.params.start == EDT_FROM_STACK {
            return self.input[s as usize * self.voxels + v];
        }
        let region = floor(self.input[v] + 0.5);
        let starts = if self.params.start == EDT_FROM_EACH_REGION {
            region == (s + 1) as f32
        } else {
            region >= 1.0 // EDT_FROM_ANY_REGION
        };
        if starts {
            0.0
        } else {
            FAR
        }
    }

    /// One line's pass into `out` (its n positions): the line's samples gathered into `f`, the
    /// lower envelope (`hull`, `bounds`) of their parabolas, then each position's lowest.
    fn pass(&self, line: (u32, u32, u32), scratch: &mut Scratch, out: &mut [f32]) {
        let Scratch { f, hull, bounds } = scratch;
        let h = self.params.spacing[self.params.axis as usize];
        f.clear();
        f.extend((0..out.len() as u32).map(|q| self.sample(q, line)));
        hull.clear();
        bounds.clear();
        for (q, &fq) in f.iter().enumerate() {
            if fq >= FAR {
                continue;
            }
            let xq = q as f32 * h;
            loop {
                let Some(&p) = hull.last() else {
                    hull.push(q);
                    bounds.push(-FAR);
                    break;
                };
                let xp = p as f32 * h;
                let s = ((fq + xq * xq) - (f[p] + xp * xp)) / (2.0 * (xq - xp));
                if s <= *bounds.last().expect("as long as hull") {
                    hull.pop();
                    bounds.pop();
                } else {
                    hull.push(q);
                    bounds.push(s);
                    break;
                }
            }
        }
        let mut k = 0;
        for (q, out) in out.iter_mut().enumerate() {
            let mut value = FAR;
            if !hull.is_empty() {
                let xq = q as f32 * h;
                while k + 1 < hull.len() && bounds[k + 1] < xq {
                    k += 1;
                }
                let e = xq - hull[k] as f32 * h;
                value = e * e + f[hull[k]];
            }
            *out = if self.params.last == 1 {
                value.sqrt()
            } else {
                value
            };
        }
    }
}

/// A line's samples and its envelope (the shader's private arrays), reused from line to line.
#[derive(Default)]
struct Scratch {
    f: Vec<f32>,
    hull: Vec<usize>,
    bounds: Vec<f32>,
}

/// Fills `output` (the stack) with one axis's pass over every line of every volume: the lines
/// in parallel, each into its own run of a buffer in line order (a + na (b + nb s)), then each
/// slice of the output gathered from it in parallel.
pub fn edt(params: &EdtParams, input: &[f32], output: &mut [f32]) {
    let d = dims3(params.dims).map(|n| n as usize);
    let voxels = d.iter().product();
    let lines = Lines {
        params,
        input,
        voxels,
    };
    let [na, nb] = params.lines();
    let axis = params.axis as usize;
    let n = d[axis];
    let mut by_line = vec![0.0f32; output.len()];
    by_line
        .par_chunks_mut(n)
        .enumerate()
        .for_each_init(Scratch::default, |scratch, (l, out)| {
            let line = (
                (l % na) as u32,
                ((l / na) % nb) as u32,
                (l / (na * nb)) as u32,
            );
            lines.pass(line, scratch, out);
        });
    let [nx, ny, nz] = d;
    output
        .par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(slice, out)| {
            let (s, z) = (slice / nz, slice % nz);
            for y in 0..ny {
                for x in 0..nx {
                    let (q, a, b) = match axis {
                        0 => (x, y, z),
                        1 => (y, x, z),
                        _ => (z, x, y),
                    };
                    out[x + nx * y] = by_line[(a + na * (b + nb * s)) * n + q];
                }
            }
        });
}
