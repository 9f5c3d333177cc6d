//! `posereg series --source S --source-labels L --targets T1 T2 ... -o DIR`: one labelled scan
//! and the same knee in several poses, in pose order. Each pose is registered as `register`
//! would, into DIR/pose_01, DIR/pose_02, …; from the second on, it is reached through the pose
//! before it (posereg::pipeline::series: the bones registered from the source with the previous pose's
//! motions tried first, their step from the previous pose blended there and composed with
//! its field), or with `--unchained` registered from the source with the previous
//! pose's bone motions tried first. DIR/series.csv tabulates every pose's kinematics.

use super::init::PairArgs;
use super::progress::Reporter;
use super::register::{register_pair, RegisterArgs, StartOf, Written};
use clap::Args;
use posereg::device::DeviceWanted;
use posereg::joints::anatomy::Side;
use posereg::joints::kinematics::KneeKinematics;
use posereg::pipeline::inputs::{check_settings, load_pair};
use posereg::pipeline::register::RegisterOptions;
use posereg::pipeline::series::{chain_step, Reached};
use posereg::report::quicklook::chart::{save_chart, Chart, Curve, Plot};
use posereg::Error;
use std::path::PathBuf;

/// Arguments of `posereg series`.
#[derive(Args, Debug)]
pub struct SeriesArgs {
    /// Source (moving) image: the scan with bone labels.
    #[arg(long, visible_alias = "moving")]
    pub source: PathBuf,
    /// Bone labels of the source, on its grid.
    #[arg(long, visible_alias = "moving-labels")]
    pub source_labels: PathBuf,
    /// The other poses (fixed images), in pose order: each is registered after the one before.
    #[arg(long, num_args = 1.., required = true)]
    pub targets: Vec<PathBuf>,
    /// Output folder: one folder per pose and series.csv.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Settings file, as `register` takes.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// The codes of the bones in your label map, as `register` takes.
    #[arg(long, value_delimiter = ',', value_parser = super::init::bone_code)]
    pub label_map: Option<Vec<(String, u16)>>,
    /// Which knee, for the kinematics (default: from the labels' fibula).
    #[arg(long, value_enum)]
    pub side: Option<Side>,
    /// Register each pose from the source with the previous pose's bone motions tried first,
    /// instead of reaching it through the previous pose (its labels carried there, the bones
    /// registered from it and the fields composed).
    #[arg(long)]
    pub unchained: bool,
}

impl SeriesArgs {
    /// `register`'s arguments for pose `index` (from 0).
    fn pose(&self, index: usize) -> RegisterArgs {
        RegisterArgs {
            pair: PairArgs {
                source: self.source.clone(),
                source_labels: self.source_labels.clone(),
                target: self.targets[index].clone(),
                output: self.output.join(format!("pose_{:02}", index + 1)),
                label_map: self.label_map.clone(),
                side: self.side,
            },
            config: self.config.clone(),
            no_init: false,
            dense: false,
            no_dense: false,
            bones: None,
            blending: None,
            reach: None,
            iterations: None,
            threshold: None,
            similarity: None,
            target_mask: None,
            init: None,
            strict: false,
        }
    }
}

/// Registers every pose in order and writes series.csv.
pub fn run(args: &SeriesArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let options = args.pose(0).options()?;
    check_every_pose(args, &options)?;
    let _folder = posereg::io::prepare_output_folder(&args.output)?;
    let mut opened = None;
    let mut previous: Option<Written> = None;
    let mut table = String::from("pose,target,joint,quantity,unit,value,change\n");
    let mut poses: Vec<(serde_json::Value, Option<KneeKinematics>)> = Vec::new();
    for index in 0..args.targets.len() {
        let pose = args.pose(index);
        reporter.say(&format!(
            "pose {} of {}: {}",
            index + 1,
            args.targets.len(),
            pose.pair.target.display()
        ));
        let chained: StartOf = &|opened, pair| {
            let Some(p) = previous.as_ref().filter(|_| !args.unchained) else {
                return Ok(None);
            };
            let reached = Reached {
                field: &p.registered.result.field,
                motions: &p.transforms,
            };
            let source = (&pair.source, &pair.labels);
            Ok(Some(posereg::on_backend!(opened, backend => chain_step(
                backend, source, reached, &pair.target, &options.init, reporter,
            ))?))
        };
        let seeds = previous.as_ref().map(|p| &p.transforms);
        let done = register_pair(
            &pose,
            &options,
            (device, &mut opened),
            (seeds, chained),
            reporter,
        )?;
        table += &kinematics_rows(index, &pose, &done);
        poses.push((done.summary.clone(), done.registered.kinematics.clone()));
        previous = Some(done);
    }
    let write = |name: &str, text: &str| {
        let path = args.output.join(name);
        posereg::io::write_atomically(&path, |tmp| {
            std::fs::write(tmp, text).map_err(|e| Error::io(tmp, e))
        })
    };
    write("series.csv", &table)?;
    write(
        "series.json",
        &(serde_json::to_string_pretty(&summary(&poses))? + "\n"),
    )?;
    save_chart(&args.output.join("series.png"), &chart(&poses))?;
    reporter.result(&format!(
        "{} poses registered; series.csv, series.json, series.png and one folder per pose in {}",
        args.targets.len(),
        args.output.display()
    ));
    Ok(())
}

/// Reads and checks every pose's inputs and the settings against them before any work: a
/// damaged last target stops the series before its first pose is registered or written.
fn check_every_pose(args: &SeriesArgs, options: &RegisterOptions) -> anyhow::Result<()> {
    for index in 0..args.targets.len() {
        let pose = args.pose(index);
        let pair = load_pair(pose.pair.paths(), &options.init.chain)?;
        check_settings(options, &pair, pose.pair.paths())?;
    }
    Ok(())
}

/// series.csv's rows for pose `index`.
fn kinematics_rows(index: usize, pose: &RegisterArgs, done: &Written) -> String {
    let mut rows = String::new();
    for joint in done.registered.kinematics.iter().flat_map(|k| &k.joints) {
        for q in &joint.quantities {
            rows += &format!(
                "{},{},{},{},{},{:.4},{:.4}\n",
                index + 1,
                pose.pair.target.display(),
                joint.joint,
                q.name,
                q.unit,
                q.target,
                q.change
            );
        }
    }
    rows
}

/// series.json: every pose's headline figures and kinematics, in pose order.
fn summary(poses: &[(serde_json::Value, Option<KneeKinematics>)]) -> serde_json::Value {
    let entries: Vec<serde_json::Value> = (poses.iter().enumerate())
        .map(|(k, (figures, kinematics))| {
            let mut entry = serde_json::json!({ "pose": k + 1 });
            entry["registration"] = figures.clone();
            entry["kinematics"] = serde_json::json!(kinematics.as_ref().map(|k| &k.joints));
            entry
        })
        .collect();
    serde_json::json!({ "schema": 1, "poses": entries })
}

/// series.png: each joint's rotations and translations, the source's values first, then each
/// pose's; the x axis names each pose with its tibiofemoral flexion.
fn chart(poses: &[(serde_json::Value, Option<KneeKinematics>)]) -> Chart {
    let joints = poses
        .iter()
        .find_map(|p| p.1.as_ref())
        .map_or(&[][..], |k| &k.joints[..]);
    let value = |pose: usize, joint: &str, name: &str| -> f64 {
        let k = poses[pose].1.as_ref();
        let j = k.and_then(|k| k.joints.iter().find(|j| j.joint == joint));
        j.and_then(|j| j.quantity(name))
            .map_or(f64::NAN, |q| q.target)
    };
    let mut labels = vec!["source".to_string()];
    labels.extend(
        (0..poses.len()).map(|p| match value(p, "tibiofemoral", "flexion") {
            f if f.is_finite() => format!("{} ({f:.0}°)", p + 1),
            _ => format!("{}", p + 1),
        }),
    );
    let mut plots = Vec::new();
    for joint in joints {
        for (unit, what) in [("deg", "rotations"), ("mm", "translations")] {
            let curves = (joint.quantities.iter().filter(|q| q.unit == unit))
                .map(|q| Curve {
                    name: q.name.replace('_', " "),
                    values: std::iter::once(q.source)
                        .chain((0..poses.len()).map(|p| value(p, joint.joint, q.name)))
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
