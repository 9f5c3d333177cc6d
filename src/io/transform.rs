//! Bone transforms on disk (truth.json, init.json, transform.json): a top-level
//! `"space": "RAS"` and `"bones": [{"label": 2, "name": "femur", "matrix": [[4 rows of 4]]}]`,
//! each matrix row-major, world RAS mm, mapping a point of the source (straight) pose to the
//! same material point in the target (bent) pose: v_target = M v_source. Other top-level keys
//! (the flexion axis of a phantom, the solver's report ...) ride along untouched.

use crate::error::{Error, Result};
use crate::volume::Affine;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The largest translation a bone motion may have: a scanner's field of view is under a metre,
/// and a bone turned about a joint half a metre from the scanner's origin moves under two.
pub const MAX_TRANSLATION_MM: f64 = 2000.0;

/// One bone's rigid motion.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoneTransform {
    /// Label code (2 femur, 3 tibia, 4 patella, 5 fibula).
    pub label: u16,
    /// Bone name.
    pub name: String,
    /// 4×4 row-major matrix, source pose → target pose, RAS mm.
    pub matrix: [[f64; 4]; 4],
}

impl BoneTransform {
    /// From an affine.
    pub fn new(label: u16, name: &str, m: &Affine) -> Self {
        BoneTransform {
            label,
            name: name.to_string(),
            matrix: std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)])),
        }
    }

    /// As an affine.
    pub fn affine(&self) -> Affine {
        Affine::from_fn(|r, c| self.matrix[r][c])
    }
}

/// The version of the bone-transform file's layout (docs/outputs.md): raised when a key
/// changes meaning or goes away. Files without one (hand-written) are read as this version.
pub const TRANSFORM_SCHEMA: u64 = 1;

/// A bone-transform file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoneTransforms {
    /// Always "RAS".
    pub space: String,
    /// One entry per bone.
    pub bones: Vec<BoneTransform>,
    /// Anything else the writer recorded.
    #[serde(flatten)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

impl BoneTransforms {
    /// RAS transforms with only the schema's version as an extra key.
    pub fn new(bones: Vec<BoneTransform>) -> Self {
        let mut extra = serde_json::Map::new();
        extra.insert("schema".into(), TRANSFORM_SCHEMA.into());
        BoneTransforms {
            space: "RAS".into(),
            bones,
            extra,
        }
    }

    /// Writes pretty JSON atomically.
    pub fn save(&self, path: &Path) -> Result<()> {
        super::save_json(path, self)
    }

    /// Refuses motions that are not rigid (rotation and translation: RᵀR = I to 10⁻³,
    /// det R = +1) or that move a bone farther than [`MAX_TRANSLATION_MM`]: the bone motions
    /// the initialisation starts from. A scale, shear or reflection would be blended into the
    /// soft tissue as if it were a rotation.
    pub fn check_rigid(&self, path: &Path) -> Result<()> {
        for b in &self.bones {
            let m = b.affine();
            let r = m.fixed_view::<3, 3>(0, 0);
            let orthogonal = (r.transpose() * r - nalgebra::Matrix3::identity())
                .abs()
                .max()
                < 1e-3;
            if !orthogonal || r.determinant() < 0.0 {
                return Err(Error::bad_file(
                    path,
                    format!(
                        "bone {} ({}): matrix is not a rotation and translation",
                        b.label, b.name
                    ),
                ));
            }
            let moved = m.fixed_view::<3, 1>(0, 3).norm();
            if moved > MAX_TRANSLATION_MM {
                return Err(Error::bad_file(
                    path,
                    format!(
                        "bone {} ({}): translation of {moved:.0} mm, beyond {MAX_TRANSLATION_MM} mm",
                        b.label, b.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Reads and checks a file: RAS space, finite rigid-or-affine matrices with last row
    /// 0 0 0 1, no label twice.
    pub fn load(path: &Path) -> Result<Self> {
        Self::parse(path, &super::read_text(path)?)
    }

    /// Parses and checks the text of the bone-transform file `path`.
    pub fn parse(path: &Path, text: &str) -> Result<Self> {
        let parsed: BoneTransforms = serde_json::from_str(text)
            .map_err(|e| Error::bad_file(path, format!("not a bone-transform file ({e})")))?;
        let schema = parsed.extra.get("schema").map(|v| v.as_u64());
        if let Some(version) = schema.filter(|v| *v != Some(TRANSFORM_SCHEMA)) {
            let problem = match version {
                Some(v) => format!("schema {v}; this posereg reads schema {TRANSFORM_SCHEMA}"),
                None => "schema is not a whole number".into(),
            };
            return Err(Error::bad_file(path, problem));
        }
        if parsed.space != "RAS" {
            return Err(Error::bad_file(
                path,
                format!("space is {:?}; posereg reads \"RAS\"", parsed.space),
            ));
        }
        for (i, b) in parsed.bones.iter().enumerate() {
            let m = &b.matrix;
            if m.iter().flatten().any(|v| !v.is_finite()) || m[3] != [0.0, 0.0, 0.0, 1.0] {
                return Err(Error::bad_file(
                    path,
                    format!(
                        "bone {} ({}): matrix must be finite with last row 0 0 0 1",
                        b.label, b.name
                    ),
                ));
            }
            let linear = nalgebra::Matrix3::from_fn(|r, c| m[r][c]);
            if linear.determinant().abs() < 1e-9 {
                return Err(Error::bad_file(
                    path,
                    format!("bone {} ({}): matrix is singular", b.label, b.name),
                ));
            }
            if parsed.bones[..i].iter().any(|o| o.label == b.label) {
                return Err(Error::bad_file(
                    path,
                    format!("label {} appears twice", b.label),
                ));
            }
        }
        Ok(parsed)
    }
}
