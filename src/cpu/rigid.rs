//! CPU twins of the rigid family's kernels (shaders/rigid/).

mod rigid_gn;
mod rigid_score;

use super::{filled, CpuBackend};
use crate::abi::{RigidParams, ScoreParams};
use crate::backend::rigid::{BoneImages, Rigid};
use crate::error::Result;
use std::sync::Arc;

impl Rigid for CpuBackend {
    fn rigid_sums(
        &self,
        params: &RigidParams,
        images: &BoneImages<Arc<Vec<f32>>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(params.columns() * crate::abi::RIGID_SUMS, |out| {
            rigid_gn::rigid_gn(params, &slices(images), out)
        })
    }

    fn rigid_scores(
        &self,
        params: &ScoreParams,
        images: &BoneImages<Arc<Vec<f32>>>,
        candidates: &Arc<Vec<f32>>,
    ) -> Result<Arc<Vec<f32>>> {
        filled(
            params.columns() * params.candidates() * crate::abi::SCORE_SUMS,
            |out| rigid_score::rigid_score(params, &slices(images), candidates, out),
        )
    }
}

/// The bone images as slices, for the twins.
fn slices<'a>(images: &BoneImages<'a, Arc<Vec<f32>>>) -> BoneImages<'a, [f32]> {
    BoneImages {
        source: images.source.as_slice(),
        mask: images.mask.as_slice(),
        target: images.target.as_slice(),
    }
}
