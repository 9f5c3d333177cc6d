//! Per-bone rigid motions as ITK text transform files (`bones/<name>.tfm`), which SimpleITK
//! (`sitk.ReadTransform`), ANTs (`antsApplyTransforms -t`) and 3D Slicer read as they are.
//!
//! ITK's transforms map a point of the fixed image (posereg's target) to the moving image
//! (posereg's source), in LPS mm; posereg's matrices map source to target in RAS. So the file
//! holds F·M⁻¹·F with F = diag(−1, −1, 1), as an AffineTransform_double_3_3 about the origin.

use super::transform::BoneTransforms;
use crate::error::{Error, Result};
use crate::volume::Affine;
use std::path::{Path, PathBuf};

/// The text of an ITK transform file for the RAS source → target motion `motion`.
pub fn itk_text(motion: &Affine) -> Result<String> {
    let inverse = motion
        .try_inverse()
        .ok_or_else(|| Error::InvalidInput("a bone motion is singular".into()))?;
    let flip = Affine::from_diagonal(&nalgebra::Vector4::new(-1.0, -1.0, 1.0, 1.0));
    let lps = flip * inverse * flip;
    let matrix = (0..3).flat_map(|r| (0..3).map(move |c| lps[(r, c)]));
    let translation = (0..3).map(|r| lps[(r, 3)]);
    let parameters: Vec<String> = matrix.chain(translation).map(|v| v.to_string()).collect();
    Ok(format!(
        "#Insight Transform File V1.0\n#Transform 0\nTransform: AffineTransform_double_3_3\n\
         Parameters: {}\nFixedParameters: 0 0 0\n",
        parameters.join(" ")
    ))
}

/// A file name for a bone: its name where that is plain letters, digits, '-' and '_', else
/// `bone<label>`.
fn file_name(label: u16, name: &str) -> String {
    let plain = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    match plain {
        true => format!("{name}.tfm"),
        false => format!("bone{label}.tfm"),
    }
}

/// Writes `folder/bones/<name>.tfm` for every bone of `transforms`, each atomically; returns
/// the paths written (none, and no folder, when there are no bones).
pub fn save_bone_tfms(folder: &Path, transforms: &BoneTransforms) -> Result<Vec<PathBuf>> {
    if transforms.bones.is_empty() {
        return Ok(Vec::new());
    }
    let bones = folder.join("bones");
    std::fs::create_dir_all(&bones).map_err(|e| Error::io(&bones, e))?;
    let mut written = Vec::new();
    for bone in &transforms.bones {
        let path = bones.join(file_name(bone.label, &bone.name));
        let text = itk_text(&bone.affine())?;
        super::write_atomically(&path, |tmp| {
            std::fs::write(tmp, &text).map_err(|e| Error::io(tmp, e))
        })?;
        written.push(path);
    }
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_file_holds_the_inverse_motion_in_lps() {
        // Source → target: a translation of +5 mm along R (RAS x). ITK maps the target point
        // back to the source: −5 mm along R, which in LPS (x = L) is +5.
        let mut m = Affine::identity();
        m[(0, 3)] = 5.0;
        let text = itk_text(&m).unwrap();
        assert!(text.starts_with("#Insight Transform File V1.0\n"), "{text}");
        assert!(
            text.contains("Parameters: 1 0 0 0 1 0 0 0 1 5 0 0\n"),
            "{text}"
        );
        assert!(text.ends_with("FixedParameters: 0 0 0\n"), "{text}");
        assert_eq!(file_name(3, "tibia"), "tibia.tfm");
        assert_eq!(file_name(7, "../x"), "bone7.tfm");
    }
}
