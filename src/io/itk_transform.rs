//! Per-bone rigid motions as ITK transform files: text (`bones/<name>.tfm`), which SimpleITK
//! (`sitk.ReadTransform`), ANTs (`antsApplyTransforms -t`) and 3D Slicer read as they are, and
//! the same transform in ITK's MATLAB v4 binary (`bones/<name>.mat`), the form ANTs writes
//! itself and the only one antspyx inverts (`whichtoinvert`).
//!
//! ITK's transforms map a point of the fixed image (posereg's target) to the moving image
//! (posereg's source), in LPS mm; posereg's matrices map source to target in RAS. So the file
//! holds F·M⁻¹·F with F = diag(−1, −1, 1), as an AffineTransform_double_3_3 about the origin.

use super::transform::BoneTransforms;
use crate::error::{Error, Result};
use crate::volume::Affine;
use std::path::{Path, PathBuf};

/// The 12 parameters of ITK's AffineTransform_double_3_3 (matrix row by row, then the
/// translation; centre at the origin) for the RAS source → target motion `motion`.
fn itk_parameters(motion: &Affine) -> Result<Vec<f64>> {
    let inverse = motion
        .try_inverse()
        .ok_or_else(|| Error::InvalidInput("a bone motion is singular".into()))?;
    let flip = Affine::from_diagonal(&nalgebra::Vector4::new(-1.0, -1.0, 1.0, 1.0));
    let lps = flip * inverse * flip;
    let matrix = (0..3).flat_map(|r| (0..3).map(move |c| lps[(r, c)]));
    let translation = (0..3).map(|r| lps[(r, 3)]);
    Ok(matrix.chain(translation).collect())
}

/// The text of an ITK transform file for the RAS source → target motion `motion`.
pub fn itk_text(motion: &Affine) -> Result<String> {
    let parameters: Vec<String> = itk_parameters(motion)?
        .iter()
        .map(|v| v.to_string())
        .collect();
    Ok(format!(
        "#Insight Transform File V1.0\n#Transform 0\nTransform: AffineTransform_double_3_3\n\
         Parameters: {}\nFixedParameters: 0 0 0\n",
        parameters.join(" ")
    ))
}

/// The same transform as ITK's MatlabTransformIO writes it: two MATLAB v4 column vectors of
/// little-endian doubles, "AffineTransform_double_3_3" (the parameters) and "fixed" (the
/// centre).
pub fn itk_mat(motion: &Affine) -> Result<Vec<u8>> {
    let mut bytes = Vec::new();
    matlab_v4_column(
        &mut bytes,
        "AffineTransform_double_3_3",
        &itk_parameters(motion)?,
    );
    matlab_v4_column(&mut bytes, "fixed", &[0.0; 3]);
    Ok(bytes)
}

/// One MATLAB v4 matrix: type 0 (little-endian doubles, full, real), rows, columns, no
/// imaginary part, the name's length with its NUL, the name, then the values column-major.
fn matlab_v4_column(bytes: &mut Vec<u8>, name: &str, values: &[f64]) {
    let header = [0, values.len() as u32, 1, 0, name.len() as u32 + 1];
    header.iter().for_each(|h| bytes.extend(h.to_le_bytes()));
    bytes.extend(name.as_bytes());
    bytes.push(0);
    values.iter().for_each(|v| bytes.extend(v.to_le_bytes()));
}

/// A file stem for a bone: its name where that is plain letters, digits, '-' and '_', else
/// `bone<label>`.
fn file_stem(label: u16, name: &str) -> String {
    let plain = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
    match plain {
        true => name.to_string(),
        false => format!("bone{label}"),
    }
}

/// Writes `folder/bones/<name>.tfm` and `.mat` for every bone of `transforms`, each
/// atomically; returns the paths written (none, and no folder, when there are no bones).
pub fn save_bone_tfms(folder: &Path, transforms: &BoneTransforms) -> Result<Vec<PathBuf>> {
    if transforms.bones.is_empty() {
        return Ok(Vec::new());
    }
    let bones = folder.join("bones");
    std::fs::create_dir_all(&bones).map_err(|e| Error::io(&bones, e))?;
    let mut written = Vec::new();
    for bone in &transforms.bones {
        let stem = bones.join(file_stem(bone.label, &bone.name));
        let motion = bone.affine();
        let files = [
            (stem.with_extension("tfm"), itk_text(&motion)?.into_bytes()),
            (stem.with_extension("mat"), itk_mat(&motion)?),
        ];
        for (path, bytes) in files {
            super::write_bytes(&path, bytes)?;
            written.push(path);
        }
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
        assert_eq!(file_stem(3, "tibia"), "tibia");
        assert_eq!(file_stem(7, "../x"), "bone7");
        // The .mat: the header ITK's MatlabTransformIO writes (type 0, 12 × 1, real, name of
        // 27 bytes), then the parameters; then "fixed", 3 × 1.
        let mat = itk_mat(&m).unwrap();
        let header: Vec<u8> = [0u32, 12, 1, 0, 27]
            .iter()
            .flat_map(|h| h.to_le_bytes())
            .collect();
        assert_eq!(&mat[..20], &header[..]);
        assert_eq!(&mat[20..47], b"AffineTransform_double_3_3\0");
        assert_eq!(&mat[47 + 9 * 8..47 + 10 * 8], &5.0f64.to_le_bytes());
        assert_eq!(mat.len(), 20 + 27 + 96 + 20 + 6 + 24);
    }
}
