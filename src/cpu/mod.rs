//! The CPU backend: each kernel's twin, written to read like its shader, parallel over slices
//! with rayon. It is a full backend (machines without a GPU use it) and the reference the GPU
//! path is tested against.

pub mod common;
pub mod compose;
pub mod gain;
pub mod jacobian;
pub mod lattice_energy;
pub mod lattice_splat;
pub mod pyramid;
pub mod rbf_adjoint;
pub mod rbf_lattice;
pub mod resample;
pub mod rigid_gn;
pub mod rigid_score;
pub mod skin_blend;
pub mod skin_weights;
pub mod ssd_cells;
pub mod sum_chunks;
pub mod sum_partials;
pub mod warp_cost;
pub mod warp_field;
pub mod warp_image;

use crate::abi::{
    BoneBlend, ComposeParams, EnergyParams, GainParams, Interpolation, JacobianParams,
    PartialsParams, PyramidParams, RbfGradParams, RbfLatticeParams, ResampleParams, RigidParams,
    ScoreParams, SkinBlendParams, SkinWeightsParams, SplatParams, SsdParams, SumParams,
};
use crate::backend::{check_pair, Backend, BoneImages, CostImages, Element, Traffic};
use crate::error::Result;
use crate::volume::{Field, Grid, Image, Volume};

/// The bone images as slices, for the twins.
fn slices<'a>(images: &BoneImages<'a, Vec<f32>>) -> BoneImages<'a, [f32]> {
    BoneImages {
        source: images.source.as_slice(),
        mask: images.mask.as_slice(),
        target: images.target.as_slice(),
    }
}

/// The cost images as slices, for the twins.
fn as_slices<'a>(images: &CostImages<'a, Vec<f32>>) -> CostImages<'a, [f32]> {
    CostImages {
        moving: images.moving.as_slice(),
        fixed: images.fixed.as_slice(),
        covered: images.covered.as_slice(),
    }
}

/// Runs every kernel on the host's cores.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuBackend;

impl Backend for CpuBackend {
    type Buffer<T: Element> = Vec<T>;

    fn upload<T: Element>(&self, _what: &str, data: Vec<T>) -> Result<Vec<T>> {
        Ok(data)
    }

    fn download<T: Element>(&self, buffers: &[&Vec<T>]) -> Result<Vec<Vec<T>>> {
        Ok(buffers.iter().map(|b| b.to_vec()).collect())
    }

    fn describe(&self) -> String {
        format!("cpu: {} threads", rayon::current_num_threads())
    }

    fn traffic(&self) -> Traffic {
        Traffic::default()
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

    fn ssd_cells(&self, params: &SsdParams, images: &CostImages<Vec<f32>>) -> Result<Vec<f32>> {
        let mut partial = vec![0.0f32; params.partials()];
        ssd_cells::ssd_cells(params, &as_slices(images), &mut partial);
        Ok(partial)
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

    fn pyramid_level(&self, params: &PyramidParams, input: &Vec<f32>) -> Result<Vec<f32>> {
        let mut data = vec![0.0f32; params.output_len()];
        pyramid::pyramid(params, input, &mut data);
        Ok(data)
    }

    fn rigid_sums(&self, params: &RigidParams, images: &BoneImages<Vec<f32>>) -> Result<Vec<f32>> {
        let mut partial = vec![0.0f32; params.columns() * crate::abi::RIGID_SUMS];
        rigid_gn::rigid_gn(params, &slices(images), &mut partial);
        Ok(partial)
    }

    fn rigid_scores(
        &self,
        params: &ScoreParams,
        images: &BoneImages<Vec<f32>>,
        candidates: &Vec<f32>,
    ) -> Result<Vec<f32>> {
        let mut partial = vec![0.0f32; params.columns() * params.candidates() * 2];
        rigid_score::rigid_score(params, &slices(images), candidates, &mut partial);
        Ok(partial)
    }

    fn skin_weights(
        &self,
        distances: &[f32],
        grid: &Grid,
        bones: usize,
        power: u32,
    ) -> Result<Vec<f32>> {
        let params = SkinWeightsParams::new(grid, bones, power);
        let mut weights = vec![0.0f32; distances.len()];
        skin_weights::skin_weights(&params, distances, &mut weights);
        Ok(weights)
    }

    fn skin_blend(
        &self,
        weights: &[f32],
        weight_grid: &Grid,
        bone_of_voxel: &[f32],
        labels: &Grid,
        target: &Grid,
        blend: &BoneBlend,
    ) -> Result<Vec<f32>> {
        crate::abi::check_bone_count(blend.motions.len())?;
        let params = SkinBlendParams::new(target, weight_grid, labels, blend);
        let mut out = vec![0.0f32; 4 * target.len()];
        skin_blend::skin_blend(&params, weights, bone_of_voxel, &mut out);
        Ok(out)
    }

    fn warp_image(
        &self,
        params: &RbfGradParams,
        lattice: &Vec<f32>,
        moving: &Vec<f32>,
    ) -> Result<Vec<f32>> {
        let mut warped = vec![0.0f32; params.voxels()];
        warp_image::warp_image(params, lattice, moving, &mut warped);
        Ok(warped)
    }

    fn gain_terms(
        &self,
        params: &GainParams,
        warped: &Vec<f32>,
        target: &Vec<f32>,
    ) -> Result<(Vec<f32>, Vec<f32>)> {
        let mut product = vec![0.0f32; params.voxels()];
        let mut energy = vec![0.0f32; params.voxels()];
        gain::gain_terms(warped, target, &mut product, &mut energy);
        Ok((product, energy))
    }

    fn gain_ratio(
        &self,
        params: &GainParams,
        product: &Vec<f32>,
        energy: &Vec<f32>,
    ) -> Result<Vec<f32>> {
        let mut gain = vec![0.0f32; params.voxels()];
        gain::gain_ratio(params, product, energy, &mut gain);
        Ok(gain)
    }

    fn gain_apply(
        &self,
        params: &GainParams,
        gain: &Vec<f32>,
        moving: &Vec<f32>,
    ) -> Result<Vec<f32>> {
        let mut gained = vec![0.0f32; params.voxels()];
        gain::gain_apply(params, gain, moving, &mut gained);
        Ok(gained)
    }

    fn warp_field(
        &self,
        lattice: &[f32],
        lattice_dims: [usize; 3],
        step: usize,
        grid: &Grid,
    ) -> Result<Field> {
        let params = RbfGradParams::new(grid, lattice_dims, step);
        let mut out = vec![0.0f32; 3 * grid.len()];
        warp_field::warp_field(&params, lattice, &mut out);
        Image::from_data(grid.clone(), bytemuck::cast_slice(&out).to_vec())
    }

    fn compose(&self, warp: &Field, initial: &Field) -> Result<Field> {
        check_pair(warp, initial)?;
        let params = ComposeParams::new(&warp.grid);
        let mut out = vec![0.0f32; 3 * warp.grid.len()];
        compose::compose(
            &params,
            bytemuck::cast_slice(&warp.data),
            bytemuck::cast_slice(&initial.data),
            &mut out,
        );
        Image::from_data(warp.grid.clone(), bytemuck::cast_slice(&out).to_vec())
    }

    fn rbf_lattice(
        &self,
        params: &RbfLatticeParams,
        geometry: &Vec<f64>,
        spline: &Vec<f64>,
    ) -> Result<Vec<f32>> {
        let mut values = vec![0.0f32; 3 * params.nodes()];
        rbf_lattice::rbf_lattice(params, geometry, spline, &mut values);
        Ok(values)
    }

    fn warp_cost(
        &self,
        params: &RbfGradParams,
        lattice: &Vec<f32>,
        images: &CostImages<Vec<f32>>,
    ) -> Result<(Vec<f32>, Vec<f32>)> {
        let [nx, ny, nz, _] = params.dims.map(|n| n as usize);
        let mut gradient = vec![0.0f32; 3 * nx * ny * nz];
        let mut rows = vec![0.0f32; ny * nz];
        warp_cost::warp_cost(
            params,
            lattice,
            &as_slices(images),
            &mut gradient,
            &mut rows,
        );
        Ok((gradient, rows))
    }

    fn lattice_splat(&self, params: &SplatParams, values: &Vec<f32>) -> Result<Vec<f32>> {
        let nodes: usize = params.dims[..3].iter().map(|&n| n as usize).product();
        let mut out = vec![0.0f32; 3 * nodes];
        lattice_splat::lattice_splat(params, values, &mut out);
        Ok(out)
    }

    fn lattice_energy(
        &self,
        params: &EnergyParams,
        lattice: &Vec<f32>,
        splat: &Vec<f32>,
    ) -> Result<(Vec<f32>, Vec<f32>)> {
        let mut gradient = vec![0.0f32; 3 * params.nodes()];
        let mut energy = vec![0.0f32; params.nodes()];
        lattice_energy::lattice_energy(params, lattice, splat, &mut gradient, &mut energy);
        Ok((gradient, energy))
    }

    fn rbf_adjoint(
        &self,
        params: &RbfLatticeParams,
        geometry: &Vec<f64>,
        spline: &Vec<f64>,
        node_gradient: &Vec<f32>,
    ) -> Result<Vec<f64>> {
        let mut partials = vec![0.0f64; 3 * params.rows() * params.chunks()];
        rbf_adjoint::rbf_adjoint(params, geometry, spline, node_gradient, &mut partials);
        Ok(partials)
    }

    fn sum_partials<T: Element>(&self, partials: &Vec<T>, values: usize) -> Result<Vec<f64>> {
        let mut sums: Option<Vec<f64>> = None;
        for pass in PartialsParams::passes(values, partials.len() / values.max(1)) {
            let mut out = vec![0.0f64; pass.groups() * values];
            match &sums {
                None => sum_partials::sum_partials(&pass, partials, &mut out),
                Some(earlier) => sum_partials::sum_partials(&pass, earlier, &mut out),
            }
            sums = Some(out);
        }
        Ok(sums.expect("at least one pass"))
    }

    fn sum_chunks(&self, params: &SumParams, values: &Vec<f32>) -> Result<Vec<f64>> {
        let mut sums = vec![0.0f64; params.chunks()];
        sum_chunks::sum_chunks(params, values, &mut sums);
        Ok(sums)
    }
}
