//! Host side of the fold family (shaders/fold/): the Jacobian determinant, the fold statistics
//! and the fold repair's masks and smoothing, their bindings, their compiled pipelines and the
//! family's trait.

use super::context::GpuContext;
use super::kernel::{cover, groups, Binding, Kernel};
use super::resident::GpuBuffer;
use super::{compile, GpuBackend};
use crate::abi::{
    push_state, AdvanceParams, BoneLookupParams, CandidateParams, DilateParams, JacobianParams,
    PushParams, RefreshParams, ThresholdParams, FOLD_STATS_WIDTH,
};
use crate::backend::fold::Fold;
use crate::error::Result;

use Binding::{Read, ReadWrite, Uniform};

/// The family's bind group layouts, by kernel name (read through super::bindings).
pub const BINDINGS: &[super::KernelBindings] = &[
    ("jacobian", &[Uniform, Read, ReadWrite]),
    ("fold_stats", &[Uniform, Read, Read, ReadWrite]),
    ("mark_at_most", &[Uniform, Read, Read, ReadWrite]),
    ("dilate", &[Uniform, Read, Read, ReadWrite]),
    ("fold_smooth", &[Uniform, Read, Read, Read, ReadWrite]),
    (
        "fold_candidates",
        &[Uniform, Read, Read, ReadWrite, ReadWrite],
    ),
    (
        "fold_push",
        &[Uniform, Read, Read, Read, ReadWrite, ReadWrite, Read],
    ),
    (
        "fold_refresh",
        &[Uniform, Read, Read, Read, ReadWrite, ReadWrite, ReadWrite],
    ),
    ("fold_advance", &[Uniform, ReadWrite, ReadWrite]),
];

/// The family's compiled kernels.
pub struct FoldKernels {
    jacobian: Kernel,
    fold_stats: Kernel,
    mark_at_most: Kernel,
    dilate: Kernel,
    fold_smooth: Kernel,
    fold_candidates: Kernel,
    fold_push: Kernel,
    fold_refresh: Kernel,
    fold_advance: Kernel,
}

impl FoldKernels {
    /// Compiles the family's kernels.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        Ok(FoldKernels {
            jacobian: compile(ctx, "jacobian")?,
            fold_stats: compile(ctx, "fold_stats")?,
            mark_at_most: compile(ctx, "mark_at_most")?,
            dilate: compile(ctx, "dilate")?,
            fold_smooth: compile(ctx, "fold_smooth")?,
            fold_candidates: compile(ctx, "fold_candidates")?,
            fold_push: compile(ctx, "fold_push")?,
            fold_refresh: compile(ctx, "fold_refresh")?,
            fold_advance: compile(ctx, "fold_advance")?,
        })
    }
}

impl Fold for GpuBackend {
    /// det(I + du/dx) for every voxel.
    fn jacobian(&self, params: &JacobianParams, field: &GpuBuffer<f32>) -> Result<GpuBuffer<f32>> {
        let det = self.output_buffer("Jacobian determinant", params.voxels())?;
        self.record(
            &self.kernels.fold.jacobian,
            params,
            &[field.raw(), det.raw()],
            cover(params.dims, 4),
        )?;
        Ok(det)
    }

    /// FOLD_STATS_WIDTH floats of fold statistics per chunk.
    fn fold_stats(
        &self,
        params: &ThresholdParams,
        det: &GpuBuffer<f32>,
        held: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let stats = self.output_buffer("fold statistics", FOLD_STATS_WIDTH * params.chunks())?;
        self.record(
            &self.kernels.fold.fold_stats,
            params,
            &[det.raw(), held.raw(), stats.raw()],
            [groups(params.chunks(), 64), 1, 1],
        )?;
        Ok(stats)
    }

    /// The voxels not held at or below the threshold.
    fn mark_at_most(
        &self,
        params: &ThresholdParams,
        value: &GpuBuffer<f32>,
        held: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let mark = self.output_buffer("marked voxels", params.voxels())?;
        self.record(
            &self.kernels.fold.mark_at_most,
            params,
            &[value.raw(), held.raw(), mark.raw()],
            cover(params.dims, 4),
        )?;
        Ok(mark)
    }

    /// One axis of a box dilation.
    fn dilate(
        &self,
        params: &DilateParams,
        mask: &GpuBuffer<f32>,
        held: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("dilated mask", params.voxels())?;
        self.record(
            &self.kernels.fold.dilate,
            params,
            &[mask.raw(), held.raw(), out.raw()],
            cover(params.dims, 4),
        )?;
        Ok(out)
    }

    /// One smoothing sweep over the region.
    fn fold_smooth(
        &self,
        params: &BoneLookupParams,
        field: &GpuBuffer<f32>,
        region: &GpuBuffer<f32>,
        labels: &GpuBuffer<f32>,
    ) -> Result<GpuBuffer<f32>> {
        let out = self.output_buffer("smoothed field", 3 * params.voxels())?;
        self.record(
            &self.kernels.fold.fold_smooth,
            params,
            &[field.raw(), region.raw(), labels.raw(), out.raw()],
            cover(params.geometry.target_dims, 4),
        )?;
        Ok(out)
    }

    /// The first list of a pass, over the whole grid.
    fn fold_candidates(
        &self,
        params: &CandidateParams,
        (det, held): (&GpuBuffer<f32>, &GpuBuffer<f32>),
        next: &mut GpuBuffer<u32>,
        state: &mut GpuBuffer<u32>,
    ) -> Result<()> {
        let bound = [det.raw(), held.raw(), next.raw(), state.raw()];
        let workgroups = cover(params.dims, 4);
        self.record(
            &self.kernels.fold.fold_candidates,
            params,
            &bound,
            workgroups,
        )
    }

    /// One invocation per voxel of the colour, as many as the state says, writing the field
    /// in place.
    fn fold_push(
        &self,
        params: &PushParams,
        voxels: &GpuBuffer<u32>,
        (rigid, labels): (&GpuBuffer<f32>, &GpuBuffer<f32>),
        field: &mut GpuBuffer<f32>,
        blocked: &mut GpuBuffer<u32>,
        (state, args): (&GpuBuffer<u32>, &GpuBuffer<u32>),
    ) -> Result<()> {
        let bound = [
            voxels.raw(),
            rigid.raw(),
            labels.raw(),
            field.raw(),
            blocked.raw(),
            state.raw(),
        ];
        let at = args_offset(params.colour as usize);
        let kernel = &self.kernels.fold.fold_push;
        self.record_indirect(kernel, params, &bound, (args.raw(), at))
    }

    /// One invocation per voxel of the sweep's list, as many as the state says.
    fn fold_refresh(
        &self,
        params: &RefreshParams,
        (voxels, next): (&GpuBuffer<u32>, &mut GpuBuffer<u32>),
        (field, held): (&GpuBuffer<f32>, &GpuBuffer<f32>),
        looked: &mut GpuBuffer<u32>,
        (state, args): (&mut GpuBuffer<u32>, &GpuBuffer<u32>),
    ) -> Result<()> {
        let bound = [
            voxels.raw(),
            field.raw(),
            held.raw(),
            next.raw(),
            looked.raw(),
            state.raw(),
        ];
        let at = args_offset(push_state::COLOURS);
        let kernel = &self.kernels.fold.fold_refresh;
        self.record_indirect(kernel, params, &bound, (args.raw(), at))
    }

    /// One invocation.
    fn fold_advance(
        &self,
        params: &AdvanceParams,
        state: &mut GpuBuffer<u32>,
        args: &mut GpuBuffer<u32>,
    ) -> Result<()> {
        let kernel = &self.kernels.fold.fold_advance;
        self.record(kernel, params, &[state.raw(), args.raw()], [1, 1, 1])
    }
}

/// Where the workgroup counts of dispatch `slot` (a colour's push, or the refresh after the
/// colours) lie in fold_advance's `args`, in bytes.
fn args_offset(slot: usize) -> u64 {
    (3 * slot * std::mem::size_of::<u32>()) as u64
}
