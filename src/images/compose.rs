//! Fields composed where the backend computes.

use crate::abi::ComposeParams;
use crate::backend::{Backend, DeviceImage};
use crate::error::Result;

/// The field `first` followed by `then`: u = first + then ∘ (id + first), on `first`'s grid
/// (`then` sampled trilinearly on its own grid).
pub fn compose<B: Backend>(
    backend: &B,
    first: &DeviceImage<B>,
    then: &DeviceImage<B>,
) -> Result<DeviceImage<B>> {
    let params = ComposeParams::new(&first.grid, &then.grid);
    Ok(DeviceImage {
        data: backend.compose(&params, &first.data, &then.data)?,
        grid: first.grid.clone(),
    })
}
