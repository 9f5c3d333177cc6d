//! Loading the fields the apply, apply-points and resample jobs share: a registration's field
//! found beside its transform.json, and the check that a reference image is on a field's grid.

use crate::abi::Interpolation;
use crate::error::{Error, Result};
use crate::io::field::load_field;
use crate::io::nifti::{load_labels, load_volume, read_header};
use crate::io::transform::BoneTransforms;
use crate::report::evaluate::seen_by_both;
use crate::volume::{Field, Image, Volume};
use std::path::{Path, PathBuf};

/// The total field of a registration: field.nii.gz in the folder of its `transform.json`
/// (which is read first, so a wrong file is refused by name), or with `inverse` its
/// inverse_field.nii.gz. Returns the field's path too.
pub fn registration_field(transform: &Path, inverse: bool) -> Result<(PathBuf, Field)> {
    let name = transform.to_string_lossy();
    if name.ends_with(".nii") || name.ends_with(".nii.gz") {
        let problem = "is an image; give the registration's transform.json (its field.nii.gz \
                       and inverse_field.nii.gz are read from the same folder)";
        return Err(Error::bad_file(transform, problem));
    }
    BoneTransforms::load(transform)?;
    let folder = transform
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let name = match inverse {
        true => "inverse_field.nii.gz",
        false => "field.nii.gz",
    };
    let path = folder.join(name);
    let field = load_field(&path)?;
    Ok((path, field))
}

/// Refuses a reference image `like` whose grid is not the grid `field` (read from
/// `field_path`) is sampled on, naming both files.
pub fn check_on_field_grid(like: &Path, field: &Field, field_path: &Path) -> Result<()> {
    let info = read_header(like)?;
    let dims: Vec<usize> = info.header.dims.iter().take(3).copied().collect();
    let affine_gap = (info.affine - field.grid.affine).abs().max();
    if dims != field.grid.dims || affine_gap > 1e-3 {
        return Err(Error::bad_file(
            like,
            format!(
                "grid {dims:?} is not the grid of the field {} ({:?}; affines differ by up to \
                 {affine_gap:.4} mm)",
                field_path.display(),
                field.grid.dims
            ),
        ));
    }
    Ok(())
}

/// The image `apply` and `resample` move: a label map (whole numbers, so that nearest
/// neighbour keeps its codes) with `nearest`, else an intensity image; refused when under 1%
/// of the points the field samples fall inside it (it would come out empty).
pub fn load_moving(path: &Path, nearest: bool, field: &Field) -> Result<Volume> {
    let image = match nearest {
        true => {
            let labels = load_labels(path)?;
            let data = labels.data.iter().map(|&l| l as f32).collect();
            Image {
                grid: labels.grid,
                data,
            }
        }
        false => load_volume(path)?,
    };
    let seen = seen_by_both(field, &image.grid, -0.5);
    let share = seen.iter().filter(|&&s| s).count() as f64 / seen.len() as f64;
    if share < 0.01 {
        let problem = format!(
            "lies outside the points the field samples ({:.1}% of them inside it): it is not \
             in the world frame of the scan the field points into",
            100.0 * share
        );
        return Err(Error::bad_file(path, problem));
    }
    Ok(image)
}

/// Nearest neighbour for label maps, trilinear otherwise.
pub fn interpolation(nearest: bool) -> Interpolation {
    if nearest {
        Interpolation::Nearest
    } else {
        Interpolation::Linear
    }
}
