//! CPU twin of shaders/edt.wgsl: one line per rayon task.

use super::common::{dims3, voxel_index};
use crate::abi::EdtParams;
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
        let c = match self.params.dims[3] {
            0 => [q, a, b],
            1 => [a, q, b],
            _ => [a, b, q],
        };
        voxel_index(c[0], c[1], c[2], dims3(self.params.dims)) as usize
    }

    /// The squared distance so far at line position q of line (a, b) of volume s.
    fn sample(&self, q: u32, (a, b, s): (u32, u32, u32)) -> f32 {
        let v = self.voxel_of(q, a, b);
        if self.params.stack[1] == 1 {
            return if (self.input[v] + 0.5).floor() == (s + 1) as f32 {
                0.0
            } else {
                FAR
            };
        }
        self.input[s as usize * self.voxels + v]
    }

    /// One line's pass into `out`: the lower envelope (`hull`, `bounds`) of the parabolas of
    /// its samples, then each position's lowest.
    fn pass(
        &self,
        line: (u32, u32, u32),
        hull: &mut Vec<u32>,
        bounds: &mut Vec<f32>,
        out: &mut Vec<f32>,
    ) {
        let axis = self.params.dims[3] as usize;
        let n = self.params.dims[axis];
        let h = self.params.spacing[axis];
        hull.clear();
        bounds.clear();
        out.clear();
        for q in 0..n {
            let fq = self.sample(q, line);
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
                let s = ((fq + xq * xq) - (self.sample(p, line) + xp * xp)) / (2.0 * (xq - xp));
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
        for q in 0..n {
            let mut value = FAR;
            if !hull.is_empty() {
                let xq = q as f32 * h;
                while k + 1 < hull.len() && bounds[k + 1] < xq {
                    k += 1;
                }
                let e = xq - hull[k] as f32 * h;
                value = e * e + self.sample(hull[k], line);
            }
            out.push(if self.params.stack[2] == 1 {
                value.sqrt()
            } else {
                value
            });
        }
    }
}

/// Fills `output` (the stack) with one axis's pass over every line of every volume.
pub fn edt(params: &EdtParams, input: &[f32], output: &mut [f32]) {
    let d = dims3(params.dims);
    let voxels = d.iter().map(|&n| n as usize).product();
    let lines = Lines {
        params,
        input,
        voxels,
    };
    let [na, nb] = params.lines().map(|n| n as u32);
    let starts: Vec<(u32, u32, u32)> = (0..params.stack[0])
        .flat_map(|s| (0..nb).flat_map(move |b| (0..na).map(move |a| (a, b, s))))
        .collect();
    let values: Vec<Vec<f32>> = starts
        .par_iter()
        .map_init(
            || (Vec::new(), Vec::new()),
            |(hull, bounds), &line| {
                let mut out = Vec::new();
                lines.pass(line, hull, bounds, &mut out);
                out
            },
        )
        .collect();
    for (&(a, b, s), values) in starts.iter().zip(values) {
        for (q, value) in values.into_iter().enumerate() {
            output[s as usize * voxels + lines.voxel_of(q as u32, a, b)] = value;
        }
    }
}
