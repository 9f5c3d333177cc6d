//! The CPU backend: each kernel's twin, written to read like its shader, parallel over slices
//! with rayon. It is a full backend (machines without a GPU use it) and the reference the GPU
//! path is tested against.

pub mod common;
pub mod jacobian;
pub mod resample;
pub mod sample;
pub mod ssd_cells;

use crate::abi::{Interpolation, JacobianParams, ResampleParams, SsdParams};
use crate::backend::{check_pair, Backend};
use crate::error::Result;
use crate::metric::{check_cells, fold_ssd_partials, CellSsd};
use crate::volume::{Field, Image, Volume};

/// Runs every kernel on the host's cores.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuBackend;

impl Backend for CpuBackend {
    fn describe(&self) -> String {
        format!("cpu: {} threads", rayon::current_num_threads())
    }

    fn resample(
        &self,
        source: &Volume,
        field: &Field,
        background: f32,
        interpolation: Interpolation,
    ) -> Result<Volume> {
        let params = ResampleParams::new(&source.grid, &field.grid, background, interpolation);
        let mut warped = vec![0.0f32; field.grid.len()];
        resample::resample(
            &params,
            &source.data,
            bytemuck::cast_slice(&field.data),
            &mut warped,
        );
        Ok(Image {
            grid: field.grid.clone(),
            data: warped,
        })
    }

    fn ssd_cells(&self, a: &Volume, b: &Volume, cells: [usize; 3]) -> Result<CellSsd> {
        check_pair(a, b)?;
        let dims = a.grid.dims;
        check_cells(dims, cells)?;
        let params = SsdParams::new(dims, cells, dims[2]);
        let mut partial = vec![0.0f32; dims[2] * dims[0] * cells[1]];
        ssd_cells::ssd_cells(&params, &a.data, &b.data, &mut partial);
        Ok(fold_ssd_partials(dims, cells, &partial))
    }

    fn jacobian(&self, field: &Field) -> Result<Volume> {
        let params = JacobianParams::new(&field.grid);
        let mut det = vec![0.0f32; field.grid.len()];
        jacobian::jacobian(&params, bytemuck::cast_slice(&field.data), &mut det);
        Ok(Image {
            grid: field.grid.clone(),
            data: det,
        })
    }
}
