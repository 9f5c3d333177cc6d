//! A synthetic pose of a labelled scan written with its truth (`posereg bend` and `pose`):
//! the scan and labels it starts from, read and checked, and what it writes.

use crate::abi::Interpolation;
use crate::backend::resample_volume;
use crate::error::{Error, Result};
use crate::init::repose::Posed;
use crate::io::field::save_field;
use crate::io::nifti::{load_labels, load_volume, save_labels, save_volume, DataType};
use crate::volume::{Labels, Volume};
use std::path::Path;

/// The scan `pose` and `bend` move and its bone labels, read and checked before any work: the
/// labels on the scan's grid.
pub fn load_posable(source: &Path, labels: &Path) -> Result<(Volume, Labels)> {
    let volume = load_volume(source)?;
    let label_map = load_labels(labels)?;
    if !label_map.grid.same_as(&volume.grid, 1e-3) {
        return Err(Error::bad_file(
            labels,
            "label map is not on the source image's grid",
        ));
    }
    Ok((volume, label_map))
}

/// Writes a synthetic pose of `source` and its `labels` into `folder`: target.nii.gz,
/// target_labels.nii.gz, truth_field.nii.gz, truth.json and picture.png (three planes through
/// `knee`).
pub fn write_posed(
    opened: &crate::device::Opened,
    folder: &std::path::Path,
    (source, labels): (&crate::Volume, &crate::Labels),
    posed: &Posed,
    knee: [f64; 3],
) -> Result<()> {
    let out = |name: &str| folder.join(name);
    let target = crate::on_backend!(opened, backend => resample_volume(backend, source, &posed.field, 0.0, Interpolation::Linear))?;
    let label_values: crate::Volume = crate::Image {
        grid: labels.grid.clone(),
        data: labels.data.iter().map(|&l| l as f32).collect(),
    };
    let target_labels = crate::on_backend!(opened, backend => resample_volume(backend, &label_values, &posed.field, 0.0, Interpolation::Nearest))?;
    save_volume(&out("target.nii.gz"), &target, DataType::F32)?;
    save_labels(
        &out("target_labels.nii.gz"),
        &crate::Image {
            grid: target_labels.grid,
            data: target_labels.data.iter().map(|&v| v as u16).collect(),
        },
    )?;
    save_field(&out("truth_field.nii.gz"), &posed.field)?;
    posed.truth.save(&out("truth.json"))?;
    crate::report::picture::save_planes_png(&out("picture.png"), &target, Some(knee))?;
    Ok(())
}
