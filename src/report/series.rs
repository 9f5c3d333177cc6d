//! series.json: what `posereg series` has finished, pose by pose, and what the series was made
//! from. It is rewritten after every pose, so a series run again on the same folder resumes
//! after the last pose finished from the same inputs and settings; series.csv and series.png
//! are drawn from these records, whichever run registered each pose.

use crate::error::{Error, Result};
use crate::joints::kinematics::KneeKinematics;
use crate::report::quicklook::chart::{Chart, Curve, Plot};
use serde::{Deserialize, Serialize};
use std::io::Read;
use std::path::Path;

/// The version of series.json's layout: raised when a key changes meaning or goes away.
pub const SERIES_SCHEMA: u32 = 2;

/// An input file as a run read it: its size and the CRC-32 of its bytes, so that a rerun tells
/// the same file (wherever it now lies) from a changed one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FileStamp {
    /// Its length in bytes.
    pub bytes: u64,
    /// CRC-32 (IEEE) of its bytes.
    pub crc32: u32,
}

impl FileStamp {
    /// Reads `path` through once.
    pub fn of(path: &Path) -> Result<Self> {
        let mut file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
        let (mut hasher, mut bytes) = (crc32fast::Hasher::new(), 0u64);
        let mut buffer = vec![0u8; 1 << 20];
        loop {
            let n = file.read(&mut buffer).map_err(|e| Error::io(path, e))?;
            if n == 0 {
                return Ok(FileStamp {
                    bytes,
                    crc32: hasher.finalize(),
                });
            }
            hasher.update(&buffer[..n]);
            bytes += n as u64;
        }
    }
}

/// Everything but the targets that decides a series' poses: a rerun keeps earlier poses only
/// when all of it is unchanged.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MadeFrom {
    /// The posereg version that registered the poses.
    pub posereg: String,
    /// The source scan.
    pub source: FileStamp,
    /// Its bone labels.
    pub source_labels: FileStamp,
    /// Poses reached through the previous one (false: `--unchained`).
    pub chained: bool,
    /// The knee's side when given (`--side`), else null.
    pub side: Option<String>,
    /// Every registration setting, as a settings file would hold them.
    pub settings: String,
}

/// One quantity of a joint, as kinematics.json holds it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct QuantityRecord {
    /// What it is ("flexion", "varus", …).
    pub name: String,
    /// "deg" or "mm".
    pub unit: String,
    /// In the source pose.
    pub source: f64,
    /// In this pose.
    pub target: f64,
    /// This pose's minus the source's.
    pub change: f64,
}

/// One joint's motion, as kinematics.json holds it: its quantities read, the rest (bones,
/// confidence) kept as written.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JointRecord {
    /// "tibiofemoral" or "patellofemoral".
    pub joint: String,
    /// Its six quantities.
    pub quantities: Vec<QuantityRecord>,
    /// Its bones and their confidence, as written.
    #[serde(flatten)]
    pub rest: serde_json::Map<String, serde_json::Value>,
}

/// One finished pose.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PoseRecord {
    /// From 1.
    pub pose: usize,
    /// Its target as it was read.
    pub target_file: FileStamp,
    /// Its registration's headline figures (report.json's).
    pub registration: serde_json::Value,
    /// Its joints' motions; None when the kinematics could not be told.
    pub kinematics: Option<Vec<JointRecord>>,
}

impl PoseRecord {
    /// The record of pose `pose` (from 1), registered onto a target read as `target_file`.
    pub fn new(
        (pose, target_file): (usize, FileStamp),
        registration: serde_json::Value,
        kinematics: Option<&KneeKinematics>,
    ) -> Result<Self> {
        let kinematics = match kinematics {
            Some(k) => Some(
                serde_json::to_value(&k.joints)
                    .and_then(serde_json::from_value)
                    .map_err(|e| Error::InvalidInput(format!("pose {pose}'s kinematics: {e}")))?,
            ),
            None => None,
        };
        Ok(PoseRecord {
            pose,
            target_file,
            registration,
            kinematics,
        })
    }

    /// Its value of `joint`'s quantity `name` in its pose, NaN when it has none.
    fn value(&self, joint: &str, name: &str) -> f64 {
        let joint = self.kinematics.iter().flatten().find(|j| j.joint == joint);
        let quantity = joint.and_then(|j| j.quantities.iter().find(|q| q.name == name));
        quantity.map_or(f64::NAN, |q| q.target)
    }
}

/// series.json's content.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SeriesFile {
    /// [`SERIES_SCHEMA`].
    pub schema: u32,
    /// What the poses were registered from.
    pub made_from: MadeFrom,
    /// The finished poses, in order from the first.
    pub poses: Vec<PoseRecord>,
}

impl SeriesFile {
    /// The poses of the series.json in `folder` that a series made from `made_from` onto
    /// targets read as `targets` keeps: none when there is no such file, it cannot be read or it
    /// was made from anything else; otherwise those up to the first whose target changed.
    pub fn finished(folder: &Path, made_from: MadeFrom, targets: &[FileStamp]) -> Self {
        let earlier = std::fs::read(folder.join("series.json")).ok();
        let earlier = earlier.and_then(|bytes| serde_json::from_slice::<SeriesFile>(&bytes).ok());
        let earlier = earlier.filter(|e| e.schema == SERIES_SCHEMA && e.made_from == made_from);
        let mut poses = earlier.map_or(Vec::new(), |e| e.poses);
        let same = poses
            .iter()
            .zip(targets)
            .enumerate()
            .take_while(|(k, (record, target))| {
                record.pose == k + 1 && record.target_file == **target
            })
            .count();
        poses.truncate(same);
        SeriesFile {
            schema: SERIES_SCHEMA,
            made_from,
            poses,
        }
    }

    /// Writes it as `folder`/series.json (atomically).
    pub fn save(&self, folder: &Path) -> Result<()> {
        crate::io::save_json(&folder.join("series.json"), self)
    }

    /// series.csv: each pose's kinematics, one quantity a row.
    pub fn table(&self) -> String {
        let mut rows = String::from("pose,target,joint,quantity,unit,value,change\n");
        for record in &self.poses {
            let target = record.registration["target"].as_str().unwrap_or_default();
            for joint in record.kinematics.iter().flatten() {
                for q in &joint.quantities {
                    rows += &format!(
                        "{},{target},{},{},{},{:.4},{:.4}\n",
                        record.pose, joint.joint, q.name, q.unit, q.target, q.change
                    );
                }
            }
        }
        rows
    }

    /// series.png: each joint's rotations and translations, the source's values first, then
    /// each pose's; the x axis names each pose with its tibiofemoral flexion.
    pub fn chart(&self) -> Chart {
        let joints = self.poses.iter().find_map(|p| p.kinematics.as_ref());
        let mut labels = vec!["source".to_string()];
        labels.extend(
            self.poses
                .iter()
                .map(|p| match p.value("tibiofemoral", "flexion") {
                    f if f.is_finite() => format!("{} ({f:.0}°)", p.pose),
                    _ => format!("{}", p.pose),
                }),
        );
        let mut plots = Vec::new();
        for joint in joints.into_iter().flatten() {
            for (unit, what) in [("deg", "rotations"), ("mm", "translations")] {
                let curves = (joint.quantities.iter().filter(|q| q.unit == unit))
                    .map(|q| Curve {
                        name: q.name.replace('_', " "),
                        values: std::iter::once(q.source)
                            .chain(self.poses.iter().map(|p| p.value(&joint.joint, &q.name)))
                            .collect(),
                    })
                    .collect();
                plots.push(Plot {
                    title: format!("{} {what}", joint.joint),
                    unit,
                    curves,
                });
            }
        }
        Chart {
            poses: labels,
            plots,
        }
    }
}
