//! CPU twin of shaders/fold/fold_push.wgsl: one colour's pushes. The colour keeps their
//! neighbourhoods apart, so each push's moves are worked out at once from the field as the
//! colour found it (on every core) and then applied: what the shader's invocations, writing in
//! place in any order, leave.

use super::push_list::bucket;
use super::stencil::{displacement, dot3, Stencil};
use crate::abi::push_state::SWEEP;
use crate::abi::{BoneLookupParams, PushParams};
use crate::sample::bone_at;
use glam::Vec3;
use rayon::prelude::*;

/// The buffers one colour's pushes read and write.
pub struct PushBuffers<'a> {
    /// The sweep's list (push_list.rs).
    pub voxels: &'a [u32],
    /// The push's state (abi::push_state).
    pub state: &'a [u32],
    /// > 0 where a voxel's displacement is its bone's motion.
    pub rigid: &'a [f32],
    /// The source label map.
    pub labels: &'a [f32],
    /// The field (3 floats per voxel), written in place.
    pub field: &'a mut [f32],
    /// The sweep each voxel was last blocked in, 0 never.
    pub blocked: &'a mut [u32],
}

/// A neighbour's new displacement, or None where it is blocked.
type Move = (usize, Option<Vec3>);

/// Pushes each of this colour's voxels that is still at or below the threshold.
pub fn fold_push(params: &PushParams, buffers: PushBuffers) {
    let lookup = BoneLookupParams {
        geometry: params.geometry,
        codes: params.codes,
        limit: 0.0,
        pad: [0; 3],
    };
    let stencil = Stencil::new(params.dims, params.mm_to_index);
    let colour = bucket(
        buffers.voxels,
        buffers.state,
        params.colour as usize,
        stencil.dims(),
    );
    let sweep = buffers.state[SWEEP];
    let push = Push {
        params,
        sweep,
        stencil,
        lookup: &lookup,
        rigid: buffers.rigid,
        labels: buffers.labels,
        field: buffers.field,
        blocked: buffers.blocked,
    };
    let moves: Vec<Vec<Move>> = colour.par_iter().map(|&n| push.moves(n as usize)).collect();
    for (q, to) in moves.into_iter().flatten() {
        match to {
            Some(u) => buffers.field[3 * q..3 * q + 3].copy_from_slice(&u.to_array()),
            None => buffers.blocked[q] = sweep,
        }
    }
}

struct Push<'a> {
    params: &'a PushParams,
    sweep: u32,
    stencil: Stencil,
    lookup: &'a BoneLookupParams,
    rigid: &'a [f32],
    labels: &'a [f32],
    field: &'a [f32],
    blocked: &'a [u32],
}

impl Push<'_> {
    fn in_bone(&self, v: usize, u: Vec3) -> bool {
        let p = self.stencil.voxel_of(v).map(|c| c as f32);
        bone_at(self.lookup, self.labels, p, u.to_array()) > 0
    }

    fn clamp_length(&self, shift: Vec3) -> Vec3 {
        let length_sq = dot3(shift, shift);
        let most = self.params.largest_step;
        if length_sq > most * most {
            shift * (most / length_sq.sqrt())
        } else {
            shift
        }
    }

    /// Where neighbour q of voxel n moves by `shift`, shortened where it would enter a bone;
    /// else the motion of n's bone extended past it (`opposite`: the neighbour across n and
    /// its displacement now); else None, blocked.
    fn move_neighbour(
        &self,
        n: usize,
        q: usize,
        opposite: (usize, Vec3),
        shift: Vec3,
    ) -> Option<Vec3> {
        let start = displacement(self.field, q);
        let inside = self.in_bone(q, start);
        let mut f = 1.0;
        for _ in 0..4 {
            let moved = start + shift * f;
            if inside || !self.in_bone(q, moved) {
                return Some(moved);
            }
            f *= 0.5;
        }
        let bone = self.rigid[n];
        let (across, across_u) = opposite;
        (bone > 0.0 && across != n && self.rigid[across] == bone)
            .then(|| 2.0 * displacement(self.field, n) - across_u)
    }

    fn may_move(&self, n: usize, q: usize) -> bool {
        let stamp = self.blocked[q];
        q != n && self.rigid[q] <= 0.0 && (stamp == 0 || stamp + 1 < self.sweep)
    }

    /// The moves of voxel n's push, in the shader's order; a neighbour across n that an
    /// earlier move of this push moved is read as moved (the shader writes in place).
    fn moves(&self, n: usize) -> Vec<Move> {
        let c = self.stencil.voxel_of(n);
        let (now, gradient) = self.stencil.det_and_gradient(self.field, c, n);
        if now > self.params.threshold {
            return Vec::new();
        }
        let mut movable: Vec<(usize, Vec3, usize)> = Vec::with_capacity(6);
        let mut norm = 0.0f32;
        for (a, ga) in gradient.iter().enumerate() {
            let s = self.stencil.arm(c, n, a);
            let g = *ga * s.factor;
            for (q, gq, across) in [(s.hi, g, s.lo), (s.lo, -g, s.hi)] {
                if self.may_move(n, q) {
                    movable.push((q, gq, across));
                    norm += dot3(g, g);
                }
            }
        }
        if norm <= f32::EPSILON {
            return Vec::new();
        }
        let step = (self.params.aim - now) / norm;
        let mut moves: Vec<Move> = Vec::with_capacity(movable.len());
        for (q, gq, across) in movable {
            let earlier = moves.iter().rev().find(|m| m.0 == across).and_then(|m| m.1);
            let across_u = earlier.unwrap_or_else(|| displacement(self.field, across));
            let shift = self.clamp_length(gq * step);
            moves.push((q, self.move_neighbour(n, q, (across, across_u), shift)));
        }
        moves
    }
}
