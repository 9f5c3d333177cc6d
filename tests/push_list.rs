//! The fold push's lists and state on the device (shaders/fold/push_list.wgsl): the first list
//! holds each voxel to lift once, in its colour's bucket, and the step between sweeps hands the
//! next list over or ends the pass, with the workgroup counts the sweep's dispatches read; both
//! backends (lavapipe in CI) alike.

mod common;

use common::{gpu, smooth_field};
use posereg::abi::push_state::{
    ARGS_LEN, COLOURS, CONTACTS_ALONE, CURRENT, LEN, LIFTED, NEXT, STOPPED, SWEEP,
};
use posereg::abi::{AdvanceParams, CandidateParams, JacobianParams, RefreshParams, Spared};
use posereg::backend::prelude::*;
use posereg::backend::DeviceImage;
use posereg::cpu::CpuBackend;
use posereg::images::unfold::FOLD_THRESHOLD;
use posereg::volume::{Affine, Grid};

/// Grid dims whose colours have different sizes (none a multiple of 3).
const DIMS: [usize; 3] = [13, 11, 8];

fn colour_of(v: usize) -> usize {
    let [nx, ny, _] = DIMS;
    v % nx % 3 + 3 * (v / nx % ny % 3) + 9 * (v / (nx * ny) % 3)
}

/// A pass's first list over a folding field with no bones, where `backend` computes.
struct FirstList<B: Backend> {
    grid: Grid,
    field: DeviceImage<B>,
    det: B::Buffer<f32>,
    held: B::Buffer<f32>,
    list: B::Buffer<u32>,
    state: B::Buffer<u32>,
}

impl<B: Backend> FirstList<B> {
    fn new(backend: &B) -> Self {
        let grid = Grid::new(DIMS, Affine::identity()).unwrap();
        let field = smooth_field(&grid, 7, 6.0);
        let field = DeviceImage::upload_field(backend, "field", field).unwrap();
        let det = backend
            .jacobian(&JacobianParams::new(&grid), &field.data)
            .unwrap();
        let held = backend.zeros("no bones", grid.len()).unwrap();
        let mut list = backend.zeros("list", grid.len()).unwrap();
        let mut state = backend.zeros("state", LEN).unwrap();
        let params = CandidateParams::new(&grid, FOLD_THRESHOLD, Spared::EnclosedByBones);
        backend
            .fold_candidates(&params, (&det, &held), &mut list, &mut state)
            .unwrap();
        FirstList {
            grid,
            field,
            det,
            held,
            list,
            state,
        }
    }
}

/// The first list of a pass, the state after it, and the field's determinant.
fn first_list<B: Backend>(backend: &B) -> (Vec<u32>, Vec<u32>, Vec<f32>) {
    let first = FirstList::new(backend);
    let list = backend.download_one(&first.list).unwrap();
    let state = backend.download_one(&first.state).unwrap();
    (list, state, backend.download_one(&first.det).unwrap())
}

/// The list a refresh makes around the first list with the field unchanged (no push
/// between), the state after it, and the voxels the refresh looked at.
fn refreshed<B: Backend>(backend: &B) -> (Vec<u32>, Vec<u32>, Vec<u32>) {
    let FirstList {
        grid,
        field,
        held,
        list,
        mut state,
        ..
    } = FirstList::new(backend);
    let mut next = backend.zeros("next list", grid.len()).unwrap();
    let mut looked = backend.zeros("looked at", grid.len()).unwrap();
    let mut args = backend.zeros("args", ARGS_LEN).unwrap();
    backend
        .fold_advance(&AdvanceParams::new(10, 5), &mut state, &mut args)
        .unwrap();
    let params = RefreshParams::new(&grid, FOLD_THRESHOLD, Spared::EnclosedByBones);
    let lists = (&list, &mut next);
    let counts = (&mut state, &args);
    backend
        .fold_refresh(&params, lists, (&field.data, &held), &mut looked, counts)
        .unwrap();
    let all = backend.download(&[&next, &state, &looked]).unwrap();
    (all[0].clone(), all[1].clone(), all[2].clone())
}

#[test]
fn a_refresh_with_nothing_pushed_lists_the_same_voxels_and_looks_around_them() {
    let (list, state, _) = first_list(&CpuBackend);
    let first = buckets(&list, &state);
    let (next, after, looked) = refreshed(&CpuBackend);
    assert_eq!(after[SWEEP], 1);
    assert_eq!(buckets(&next, &after), first, "the same voxels, each once");
    let [nx, ny, _] = DIMS;
    let at = |v: usize| [v % nx, v / nx % ny, v / (nx * ny)].map(|i| i as i64);
    let listed: Vec<usize> = first.iter().flatten().map(|&v| v as usize).collect();
    for (v, &stamp) in looked.iter().enumerate() {
        let near = listed.iter().any(|&n| {
            let (a, b) = (at(v), at(n));
            (0..3).map(|k| (a[k] - b[k]).abs()).sum::<i64>() <= 2
        });
        assert_eq!(
            stamp, near as u32,
            "voxel {v} looked at in sweep 1 iff near a listed one"
        );
    }
    if let Some(gpu) = gpu() {
        let (gpu_next, gpu_after, gpu_looked) = refreshed(gpu);
        assert_eq!(buckets(&gpu_next, &gpu_after), first);
        assert_eq!(gpu_after, after);
        assert_eq!(gpu_looked, looked);
    }
}

/// Each colour's bucket of `list` (as many as `state` counts), sorted.
fn buckets(list: &[u32], state: &[u32]) -> Vec<Vec<u32>> {
    let sizes: Vec<usize> = (0..COLOURS)
        .map(|c| {
            (0..DIMS.iter().product())
                .filter(|&v| colour_of(v) == c)
                .count()
        })
        .collect();
    let mut start = 0;
    (0..COLOURS)
        .map(|c| {
            let mut bucket = list[start..start + state[NEXT + c] as usize].to_vec();
            bucket.sort_unstable();
            start += sizes[c];
            bucket
        })
        .collect()
}

#[test]
fn the_first_list_holds_each_voxel_to_lift_once_in_its_colours_bucket() {
    let (list, state, det) = first_list(&CpuBackend);
    let folded: Vec<usize> = (0..det.len())
        .filter(|&v| det[v] <= FOLD_THRESHOLD)
        .collect();
    assert!(
        folded.len() > 20,
        "the field must fold: {} voxels",
        folded.len()
    );
    assert!(folded.len() < det.len() / 4, "and not everywhere");
    let cpu = buckets(&list, &state);
    for (c, bucket) in cpu.iter().enumerate() {
        let expected: Vec<u32> = folded
            .iter()
            .filter(|&&v| colour_of(v) == c)
            .map(|&v| v as u32)
            .collect();
        assert_eq!(bucket, &expected, "colour {c}");
    }
    assert_eq!(
        state[LIFTED] as usize,
        folded.len(),
        "no bones: none a contact"
    );
    assert_eq!(state[SWEEP], 0);
    if let Some(gpu) = gpu() {
        let (list, gpu_state, _) = first_list(gpu);
        assert_eq!(buckets(&list, &gpu_state), cpu);
        assert_eq!(gpu_state, state);
    }
}

/// The state and workgroup counts after one step from `state`.
fn advanced<B: Backend>(
    backend: &B,
    state: &[u32],
    params: &AdvanceParams,
) -> (Vec<u32>, Vec<u32>) {
    let mut state = backend.upload("state", state.to_vec()).unwrap();
    let mut args = backend.zeros("args", ARGS_LEN).unwrap();
    backend.fold_advance(params, &mut state, &mut args).unwrap();
    let both = backend.download(&[&state, &args]).unwrap();
    (both[0].clone(), both[1].clone())
}

/// A state in sweep `sweep` whose next list has `counts` voxels of the first colours.
fn state_with(sweep: u32, counts: &[u32], lifted: u32, alone: u32) -> Vec<u32> {
    let mut state = vec![0; LEN];
    state[SWEEP] = sweep;
    state[LIFTED] = lifted;
    state[CONTACTS_ALONE] = alone;
    state[NEXT..NEXT + counts.len()].copy_from_slice(counts);
    state
}

/// Steps `state` on the CPU, and on the GPU when there is one, which must agree.
fn advanced_on_both(state: &[u32], params: &AdvanceParams) -> (Vec<u32>, Vec<u32>) {
    let cpu = advanced(&CpuBackend, state, params);
    if let Some(gpu) = gpu() {
        assert_eq!(advanced(gpu, state, params), cpu);
    }
    cpu
}

#[test]
fn a_step_between_sweeps_hands_the_next_list_over_or_ends_the_pass() {
    let params = AdvanceParams::new(100, 5);
    // 3,000,000 voxels need 46,875 workgroups of 64: two rows of at most 32,768.
    let (state, args) = advanced_on_both(&state_with(7, &[65, 0, 3_000_000], 2, 3), &params);
    assert_eq!(
        (state[SWEEP], state[STOPPED], state[CONTACTS_ALONE]),
        (8, 0, 0)
    );
    assert_eq!(&state[CURRENT..CURRENT + 3], &[65, 0, 3_000_000]);
    assert!(state[NEXT..NEXT + COLOURS].iter().all(|&n| n == 0));
    assert_eq!(state[LIFTED], 0);
    assert_eq!(&args[0..9], &[2, 1, 1, 0, 0, 1, 32768, 2, 1]);
    assert_eq!(
        &args[3 * COLOURS..],
        &[32768, 2, 1],
        "the refresh covers the whole list"
    );

    // Only bone contacts left (nothing lifted) for the fifth sweep in a row: the pass ends.
    let (state, args) = advanced_on_both(&state_with(7, &[4], 0, 4), &params);
    assert_eq!(
        (state[SWEEP], state[STOPPED], state[CONTACTS_ALONE]),
        (7, 1, 5)
    );
    assert!(args.iter().all(|&a| a == 0 || a == 1) && args.chunks(3).all(|g| g[0] == 0));
    // The first step (sweep 0) counts nothing: the first list is no sweep's result.
    let (state, _) = advanced_on_both(&state_with(0, &[4], 0, 4), &params);
    assert_eq!(
        (state[SWEEP], state[STOPPED], state[CONTACTS_ALONE]),
        (1, 0, 4)
    );

    // Nothing left to lift, or the most sweeps run: the pass ends, and a step after does
    // nothing.
    for ended in [state_with(7, &[], 3, 0), state_with(100, &[9], 3, 0)] {
        let (state, args) = advanced_on_both(&ended, &params);
        assert_eq!(state[STOPPED], 1);
        assert!(state[CURRENT..CURRENT + COLOURS].iter().all(|&n| n == 0));
        assert!(args.chunks(3).all(|g| g[0] == 0 && g[1] == 0));
        assert_eq!(advanced_on_both(&state, &params).0, state);
    }
}

/// A kernel dispatched again with the same parameters (each colour's push, every sweep) sends
/// them up once: the GPU backend makes one uniform buffer per distinct parameter struct.
#[test]
fn parameters_dispatched_again_go_up_once() {
    if gpu().is_none() {
        return;
    }
    // A backend of its own: the shared one counts the other tests' traffic too.
    let gpu = posereg::gpu::GpuBackend::new().unwrap();
    let mut state = gpu.zeros("state", LEN).unwrap();
    let mut args = gpu.zeros("args", ARGS_LEN).unwrap();
    let before = gpu.traffic().bytes_up;
    let (a, b) = (AdvanceParams::new(3, 5), AdvanceParams::new(4, 5));
    for params in [&a, &a, &b, &a, &b] {
        gpu.fold_advance(params, &mut state, &mut args).unwrap();
    }
    let state = gpu.download_one(&state).unwrap();
    assert_eq!(state[STOPPED], 1, "nothing listed: the pass ends");
    let sent = gpu.traffic().bytes_up - before;
    assert_eq!(sent, 2 * std::mem::size_of::<AdvanceParams>() as u64);
}
