//! `posereg series --source S --source-labels L --targets T1 T2 ... -o DIR`: one labelled scan
//! and the same knee in several poses, in pose order. Each pose is registered as `register`
//! would, into DIR/pose_01, DIR/pose_02, …, with the previous pose's bone motions tried first by
//! the rigid search (a neighbouring pose is the best guess for the next); DIR/series.csv
//! tabulates every pose's kinematics.

use super::init::PairArgs;
use super::progress::Reporter;
use super::register::{register_pair, RegisterArgs};
use clap::Args;
use posereg::anatomy::Side;
use posereg::device::DeviceWanted;
use posereg::io::transform::BoneTransforms;
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
            bones: None,
            blending: None,
            iterations: None,
            threshold: None,
            target_mask: None,
            init: None,
            strict: false,
        }
    }
}

/// Registers every pose in order and writes series.csv.
pub fn run(args: &SeriesArgs, device: &DeviceWanted, reporter: &Reporter) -> anyhow::Result<()> {
    let options = args.pose(0).options()?;
    let _folder = posereg::io::prepare_output_folder(&args.output)?;
    let mut opened = None;
    let mut previous: Option<BoneTransforms> = None;
    let mut table = String::from("pose,target,joint,quantity,unit,value,change\n");
    for index in 0..args.targets.len() {
        let pose = args.pose(index);
        reporter.say(&format!(
            "pose {} of {}: {}",
            index + 1,
            args.targets.len(),
            pose.pair.target.display()
        ));
        let done = register_pair(
            &pose,
            &options,
            (device, &mut opened),
            previous.as_ref(),
            reporter,
        )?;
        for joint in done.kinematics.iter().flat_map(|k| &k.joints) {
            for q in &joint.quantities {
                table += &format!(
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
        previous = Some(done.transforms);
    }
    let path = args.output.join("series.csv");
    posereg::io::write_atomically(&path, |tmp| {
        std::fs::write(tmp, &table).map_err(|e| Error::io(tmp, e))
    })?;
    reporter.result(&format!(
        "{} poses registered; series.csv and one folder per pose in {}",
        args.targets.len(),
        args.output.display()
    ));
    Ok(())
}
