//! The fold push (images::unfold) on both backends: it lifts folds beside a bone without moving
//! the bone or carrying tissue into it, moves tissue caught inside a bone off the bone's motion,
//! extends a bone's motion to the tissue voxel behind it where no push can lift the fold, and
//! the GPU path (lavapipe in CI) gives the CPU path's field.

mod common;

use common::gpu;
use posereg::abi::{BoneLookupParams, JacobianParams};
use posereg::backend::prelude::*;
use posereg::backend::DeviceImage;
use posereg::cpu::CpuBackend;
use posereg::images::fold_repair::host_determinant;
use posereg::images::unfold::{unfold, Bones, Held, FOLD_THRESHOLD};
use posereg::volume::{Affine, Field, Grid, Image};

/// A field on an n³ grid (identity affine), the source labels (the bone is code 2, tissue 1)
/// and which voxels are held in the bone by their source point and at its motion.
struct Fixture {
    field: Field,
    codes: Vec<f32>,
    bones: Vec<f32>,
    rigid: Vec<f32>,
}

/// Unfolds the fixture on `backend`: the field after, and the sweeps.
fn unfolded<B: Backend>(backend: &B, f: &Fixture) -> (Field, usize) {
    let grid = f.field.grid.clone();
    let field = DeviceImage::upload_field(backend, "field", f.field.clone()).unwrap();
    let bones = backend.upload("bones", f.bones.clone()).unwrap();
    let rigid = backend.upload("rigid", f.rigid.clone()).unwrap();
    let labels = backend.upload("labels", f.codes.clone()).unwrap();
    let lookup = BoneLookupParams::new(&grid, &grid, &[2], f32::MAX).unwrap();
    let held = Held {
        bones: &bones,
        rigid: &rigid,
    };
    let in_bones = Bones {
        lookup: &lookup,
        labels: &labels,
    };
    let det = backend
        .jacobian(&JacobianParams::new(&grid), &field.data)
        .unwrap();
    let (out, sweeps) = unfold(backend, (&field, &det), &held, &in_bones).unwrap();
    (out.download_field(backend).unwrap(), sweeps)
}

/// The least det J of `field` (the jacobian kernel on the CPU).
fn least_det(field: &Field) -> f32 {
    let det = host_determinant(&CpuBackend, field).unwrap();
    det.iter().cloned().fold(f32::INFINITY, f32::min)
}

/// Unfolds on the CPU, and on the GPU when there is one, which must give the same field (twice
/// the same bits); returns the CPU's after asserting that the fixture folded before.
fn unfolded_on_both(f: &Fixture) -> Field {
    assert!(least_det(&f.field) <= 0.0, "the fixture must fold");
    let (cpu, sweeps) = unfolded(&CpuBackend, f);
    if let Some(gpu) = gpu() {
        let (got, gpu_sweeps) = unfolded(gpu, f);
        assert_eq!(gpu_sweeps, sweeps);
        // The lists' order within a colour varies from run to run on a GPU; the pushes of
        // one colour do not depend on it, so the field must not either.
        let (again, _) = unfolded(gpu, f);
        assert!(again.data == got.data, "two GPU runs differ");
        let most = got
            .data
            .iter()
            .zip(&cpu.data)
            .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
            .fold(0.0f32, f32::max);
        assert!(most < 1e-4, "GPU and CPU fields {most} mm apart");
    }
    cpu
}

/// Code 2 (the bone) where `bone(i)` holds for the voxel's x index, 1 elsewhere.
fn slab(n: usize, bone: impl Fn(usize) -> bool) -> Vec<f32> {
    (0..n * n * n)
        .map(|m| if bone(m % n) { 2.0 } else { 1.0 })
        .collect()
}

/// Which voxels of `field` the source labels `codes` hold in the bone, by their source point.
fn in_bone(field: &Field, codes: &[f32]) -> Vec<f32> {
    let n = field.grid.dims[0];
    (0..field.grid.len())
        .map(|m| {
            let x = (m % n) as f32 + field.data[m][0];
            let inside = x.round() >= 0.0 && codes[m - m % n + x.round() as usize] == 2.0;
            if inside {
                2.0
            } else {
                0.0
            }
        })
        .collect()
}

fn grid(n: usize) -> Grid {
    Grid::new([n, n, n], Affine::identity()).unwrap()
}

/// A field that folds along x beside a bone whose voxels must not move: u_x falls by 2.4 mm
/// over two voxels around x = 8 (det −0.2), the bone the slab x ≥ 8 of the source labels,
/// which the field maps to x ≥ 10, right beside the fold. The push lifts every voxel above the
/// threshold and leaves the bone's displacements as they were.
#[test]
fn the_push_lifts_a_fold_pinned_by_a_bone_on_both_backends() {
    let n = 16;
    let data: Vec<[f32; 3]> = (0..n * n * n)
        .map(|m| {
            let i = (m % n) as f32;
            [-2.4 * ((i - 7.0) / 2.0).clamp(0.0, 1.0), 0.0, 0.0]
        })
        .collect();
    let field = Image::from_data(grid(n), data).unwrap();
    let codes = slab(n, |x| x >= 8);
    let held = in_bone(&field, &codes);
    let fixture = Fixture {
        field,
        codes,
        bones: held.clone(),
        rigid: held.clone(),
    };
    let after = unfolded_on_both(&fixture);
    assert!(least_det(&after) > FOLD_THRESHOLD, "{}", least_det(&after));
    assert!(held.iter().any(|&h| h > 0.0));
    for m in (0..held.len()).filter(|&m| held[m] > 0.0) {
        assert_eq!(fixture.field.data[m], after.data[m], "bone voxel {m} moved");
    }
}

/// The bone is the slab 4 ≤ x ≤ 7, which the field leaves where it is; the tissue voxel x = 8
/// maps `shift` voxels along x.
fn shifted_beside_a_slab(n: usize, shift: f32) -> (Field, Vec<f32>) {
    let data: Vec<[f32; 3]> = (0..n * n * n)
        .map(|m| [if m % n == 8 { shift } else { 0.0 }, 0.0, 0.0])
        .collect();
    (
        Image::from_data(grid(n), data).unwrap(),
        slab(n, |x| (4..=7).contains(&x)),
    )
}

/// The tissue voxel x = 8 maps to x = 5.5, inside the bone, folding the bone voxel x = 7 (det
/// −0.25). Held at the bone's motion only where the field is the bone's motion, x = 8 moves
/// out and the fold lifts; held as bone by its source point alone, nothing may move.
#[test]
fn tissue_inside_a_bone_off_its_motion_may_move() {
    let n = 16;
    let (field, codes) = shifted_beside_a_slab(n, -2.5);
    let by_source = in_bone(&field, &codes);
    let at_motion: Vec<f32> = (0..field.grid.len())
        .map(|m| {
            if by_source[m] > 0.0 && field.data[m] == [0.0; 3] {
                2.0
            } else {
                0.0
            }
        })
        .collect();
    let fixture = |rigid: &[f32]| Fixture {
        field: field.clone(),
        codes: codes.clone(),
        bones: by_source.clone(),
        rigid: rigid.to_vec(),
    };
    let stays = unfolded(&CpuBackend, &fixture(&by_source)).0;
    assert!(
        least_det(&stays) <= 0.0,
        "held by source point, the fold stays"
    );
    let lifted = unfolded_on_both(&fixture(&at_motion));
    assert!(
        least_det(&lifted) > FOLD_THRESHOLD,
        "{}",
        least_det(&lifted)
    );
}

/// The tissue voxel x = 8 maps to x = 2, behind the bone: det −2 at x = 7. Every push that lifts
/// it carries x = 8's source point into the bone, so it moves with the bone instead.
#[test]
fn a_tissue_voxel_behind_a_bone_moves_with_the_bone() {
    let n = 16;
    let (field, codes) = shifted_beside_a_slab(n, -6.0);
    let held = in_bone(&field, &codes);
    let fixture = Fixture {
        field,
        codes,
        bones: held.clone(),
        rigid: held,
    };
    let after = unfolded_on_both(&fixture);
    assert!(least_det(&after) > FOLD_THRESHOLD, "{}", least_det(&after));
    let behind = 8 + n * (7 + n * 7);
    assert_eq!(after.data[behind], [0.0; 3], "x = 8 moves as the bone does");
}
