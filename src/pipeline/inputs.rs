//! A registration's inputs, loaded and checked so that every problem is found before any work
//! starts and is named with its file: headers first (3-D grids, the labels on the source's
//! grid, the scans overlapping, memory), then the voxels, then their content (an image with
//! nothing to register, no bones, bones too small, label codes that are not bones), then the
//! settings against the inputs (the bones they name exist and are in the chain, the target holds
//! the pyramid levels asked for).

use crate::error::{Error, Result};
use crate::images::pyramid::next_level_grid;
use crate::init::articulated::InitOptions;
use crate::io::memory;
use crate::io::nifti::{
    check_finite, labels_from_raw, read_header, read_raw, spatial_grid, volume_from_raw,
};
use crate::io::transform::BoneTransforms;
use crate::joints::chain::{self, Link};
use crate::pipeline::register::RegisterOptions;
use crate::volume::{Grid, Labels, Volume};
use std::path::Path;

/// Bytes a registration holds per target voxel at its peak: `posereg demo` (half phantom,
/// 68×128×128, CPU backend) peaked at 188 MB resident over 1.1 M voxels, 170 bytes a voxel;
/// more than doubled for a source larger than the target. Checked against the memory budget
/// before reading any voxel.
const BYTES_PER_TARGET_VOXEL: u64 = 400;
/// Least share of an image's voxels above its background (its smallest value).
const MIN_CONTENT_SHARE: f64 = 0.01;
/// A bone with fewer voxels than this gives its rigid registration nothing to hold on to.
const MIN_BONE_VOXELS: usize = 64;
/// Label codes that are not bones but are expected: 0 outside, 1 soft tissue (phantom).
const NON_BONE_CODES: [u16; 2] = [0, 1];

/// Where the three inputs are.
#[derive(Clone, Copy, Debug)]
pub struct PairPaths<'a> {
    /// The straight scan.
    pub source: &'a Path,
    /// Its bone labels.
    pub labels: &'a Path,
    /// The bent scan.
    pub target: &'a Path,
}

/// The inputs, read and checked.
pub struct Pair {
    /// The straight scan.
    pub source: Volume,
    /// Its bone labels.
    pub labels: Labels,
    /// The bent scan.
    pub target: Volume,
    /// What the user should know but that does not stop the registration.
    pub warnings: Vec<String>,
}

/// Reads the three inputs after checking their headers against each other; the label map
/// must hold a bone of `chain`.
pub fn load_pair(paths: PairPaths, chain: &[Link]) -> Result<Pair> {
    let grid_of = |path: &Path, what: &str| spatial_grid(path, &read_header(path)?, what);
    let source_grid = grid_of(paths.source, "an intensity image")?;
    let label_grid = grid_of(paths.labels, "a label map")?;
    let target_grid = grid_of(paths.target, "an intensity image")?;
    if !label_grid.same_as(&source_grid, 1e-3) {
        return Err(Error::bad_file(
            paths.labels,
            format!(
                "label map grid {:?} differs from the source's ({:?}, {})",
                label_grid.dims,
                source_grid.dims,
                paths.source.display()
            ),
        ));
    }
    check_overlap(&target_grid, &source_grid, paths)?;
    let needed = (target_grid.len() as u64).saturating_mul(BYTES_PER_TARGET_VOXEL);
    memory::check(needed).map_err(|p| {
        Error::bad_file(
            paths.target,
            format!("registering onto its {:?} voxels {p}", target_grid.dims),
        )
    })?;
    let source = volume_from_raw(paths.source, read_raw(paths.source)?)?;
    let labels = labels_from_raw(paths.labels, read_raw(paths.labels)?)?;
    let target = volume_from_raw(paths.target, read_raw(paths.target)?)?;
    checked_content(source, labels, target, paths, chain)
}

/// Checks three inputs that did not come from files (the Python package's arrays; `names`
/// says what to call them): the labels on the source's grid, the scans overlapping, and their
/// content, as [`load_pair`] and its reads check files (voxels finite).
pub fn check_pair(
    source: Volume,
    labels: Labels,
    target: Volume,
    names: PairPaths,
    chain: &[Link],
) -> Result<Pair> {
    if !labels.grid.same_as(&source.grid, 1e-3) {
        return Err(Error::bad_file(
            names.labels,
            format!(
                "label map grid {:?} differs from the source's",
                labels.grid.dims
            ),
        ));
    }
    check_overlap(&target.grid, &source.grid, names)?;
    check_finite(names.source, &source.data)?;
    check_finite(names.target, &target.data)?;
    checked_content(source, labels, target, names, chain)
}

/// The pair after its content checks: neither scan constant, the labels holding bones.
fn checked_content(
    source: Volume,
    labels: Labels,
    target: Volume,
    paths: PairPaths,
    chain: &[Link],
) -> Result<Pair> {
    check_not_constant(&source, paths.source)?;
    check_not_constant(&target, paths.target)?;
    let warnings = check_labels(&labels, paths.labels, chain)?;
    Ok(Pair {
        source,
        labels,
        target,
        warnings,
    })
}

/// The bone motions given to start from (`--init`: transform.json or init.json of an earlier
/// run) read from `path`: rigid, each for a bone present in `labels`, and one for every bone
/// `options` registers.
pub fn load_given_motions(
    path: &Path,
    labels: &Labels,
    options: &InitOptions,
) -> Result<BoneTransforms> {
    let given = BoneTransforms::load(path)?;
    given.check_rigid(path)?;
    let present = chain::present(&options.chain, labels);
    if let Some(b) = given.bones.iter().find(|b| !present.contains(&b.label)) {
        let problem = format!(
            "bone {} ({}) is not among the labels' bones {present:?}",
            b.label, b.name
        );
        return Err(Error::bad_file(path, problem));
    }
    let registered = options.bones_in(labels);
    if let Some(b) = registered
        .iter()
        .find(|b| !given.bones.iter().any(|g| g.label == **b))
    {
        return Err(Error::bad_file(
            path,
            format!("has no transform for bone label {b}"),
        ));
    }
    Ok(given)
}

/// Reads a target mask (`--target-mask`): a label map on the target's grid whose non-zero
/// voxels are the evidence the non-rigid stage fits. Refused when on another grid or when it
/// holds less than [`MIN_CONTENT_SHARE`] of the target.
pub fn load_target_mask(path: &Path, target: &Grid, target_path: &Path) -> Result<Labels> {
    let grid = spatial_grid(path, &read_header(path)?, "a mask")?;
    if !grid.same_as(target, 1e-3) {
        return Err(Error::bad_file(
            path,
            format!(
                "mask grid {:?} differs from the target's ({:?}, {}): a target mask must be on \
                 the target's grid",
                grid.dims,
                target.dims,
                target_path.display()
            ),
        ));
    }
    let mask = labels_from_raw(path, read_raw(path)?)?;
    let inside = mask.data.iter().filter(|&&m| m > 0).count();
    let share = inside as f64 / mask.data.len() as f64;
    if share < MIN_CONTENT_SHARE {
        return Err(Error::bad_file(
            path,
            format!(
                "the mask holds {inside} voxels ({:.3}% of the target): too few to register on",
                100.0 * share
            ),
        ));
    }
    Ok(mask)
}

fn check_overlap(target: &Grid, source: &Grid, paths: PairPaths) -> Result<()> {
    let overlap = target.share_inside(source);
    if overlap < 0.01 {
        return Err(Error::bad_file(
            paths.target,
            format!(
                "its field of view does not overlap the source's ({}; {:.1}% of it inside): the \
                 scans must share a world frame",
                paths.source.display(),
                100.0 * overlap
            ),
        ));
    }
    Ok(())
}

/// An image whose voxels are (almost) all one value holds nothing to register against: every
/// voxel the same, or fewer than [`MIN_CONTENT_SHARE`] of them above the background (its
/// smallest value). A target holding one bright voxel once registered into a field folded on
/// 46% of its voxels.
fn check_not_constant(volume: &Volume, path: &Path) -> Result<()> {
    let background = volume.data.iter().copied().fold(f32::INFINITY, f32::min);
    let content = volume.data.iter().filter(|&&v| v > background).count();
    if content == 0 {
        return Err(Error::bad_file(
            path,
            format!("every voxel is {background}: an image with no contrast cannot be registered"),
        ));
    }
    let share = content as f64 / volume.data.len() as f64;
    if share < MIN_CONTENT_SHARE {
        return Err(Error::bad_file(
            path,
            format!(
                "is almost empty: {content} voxels ({:.3}%) are above its background {background}; \
                 an image with no contrast cannot be registered",
                100.0 * share
            ),
        ));
    }
    Ok(())
}

/// Refuses a label map without a bone of `chain`; returns a warning for codes that are
/// neither bones of the chain nor outside / soft tissue.
fn check_labels(labels: &Labels, path: &Path, chain: &[Link]) -> Result<Vec<String>> {
    let bones = chain::described(chain);
    if chain::present(chain, labels).is_empty() {
        return Err(Error::bad_file(
            path,
            format!("has no bone labels ({bones})"),
        ));
    }
    let mut others: Vec<u16> = labels
        .data
        .iter()
        .copied()
        .filter(|c| !NON_BONE_CODES.contains(c) && chain::link(chain, *c).is_none())
        .collect();
    others.sort_unstable();
    others.dedup();
    if others.is_empty() {
        return Ok(Vec::new());
    }
    let codes: Vec<String> = others.iter().map(|c| c.to_string()).collect();
    Ok(vec![format!(
        "{}: label codes {} are not bones of the kinematic chain ({bones}); they are treated \
         as soft tissue (--label-map names the codes of your bones)",
        path.display(),
        codes.join(", ")
    )])
}

/// Checks the settings against the inputs: with the initialisation, every bone it registers
/// exists, is large enough and is in the chain; the target holds the
/// pyramid levels asked for.
pub fn check_settings(options: &RegisterOptions, pair: &Pair, paths: PairPaths) -> Result<()> {
    if options.initialise {
        check_bones(&options.init, &pair.labels, paths)?;
    }
    check_levels(&pair.target.grid, options.adaptive.levels, paths.target)
}

/// Every bone the initialisation registers has enough voxels and a place in the chain.
pub fn check_bones(init: &InitOptions, labels: &Labels, paths: PairPaths) -> Result<()> {
    let present = chain::present(&init.chain, labels);
    let listed = |codes: &[u16]| {
        codes
            .iter()
            .map(|c| c.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let chosen = init.bones_in(labels);
    for &bone in &chosen {
        let count = labels.data.iter().filter(|&&l| l == bone).count();
        if count == 0 {
            return Err(Error::bad_file(
                paths.labels,
                format!(
                    "has no voxels of bone {bone} named by --bones / init.bones (bones present: {})",
                    listed(&present)
                ),
            ));
        }
        if count < MIN_BONE_VOXELS {
            return Err(Error::bad_file(
                paths.labels,
                format!(
                    "{} (label {bone}) has {count} voxels, too few to register (at least \
                     {MIN_BONE_VOXELS}); leave it out with --bones",
                    init.name_of(bone)
                ),
            ));
        }
    }
    if let Some(bone) = chosen
        .iter()
        .find(|&&b| crate::joints::chain::link(&init.chain, b).is_none())
    {
        return Err(Error::InvalidInput(format!(
            "bone label {bone} (from --bones or {}) has no entry in init.chain; add one with \
             its parent",
            paths.labels.display()
        )));
    }
    Ok(())
}

/// The target must give the pyramid levels asked for (an axis is halved only while it keeps
/// enough voxels, crate::images::pyramid).
pub fn check_levels(target: &Grid, levels: usize, path: &Path) -> Result<()> {
    let mut available = 1;
    let mut grid = target.clone();
    while available < levels {
        let Some((coarser, _)) = next_level_grid(&grid) else {
            break;
        };
        grid = coarser;
        available += 1;
    }
    if available < levels {
        return Err(Error::bad_file(
            path,
            format!(
                "its {:?} voxels give {available} pyramid level(s), but adaptive.levels asks for \
                 {levels}: use a larger image or fewer levels",
                target.dims
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Affine, Image};

    #[test]
    fn label_codes_are_read_against_the_chain() {
        let grid = Grid::new([4, 1, 1], Affine::identity()).unwrap();
        let labels: Labels = Image::from_data(grid, vec![0, 1, 7, 7]).unwrap();
        let path = Path::new("ankle_labels.nii.gz");
        let knee = check_labels(&labels, path, &chain::knee())
            .unwrap_err()
            .to_string();
        assert!(
            knee.contains("has no bone labels (2 femur, 3 tibia"),
            "{knee}"
        );
        let talus = vec![Link {
            label: 7,
            name: "talus".into(),
            parent: None,
            search_degrees: None,
            max_degrees: 0.0,
        }];
        assert_eq!(
            check_labels(&labels, path, &talus).unwrap(),
            Vec::<String>::new()
        );
        let mut femur_only = talus.clone();
        femur_only[0].label = 2;
        femur_only[0].name = "femur".into();
        let grid = Grid::new([4, 1, 1], Affine::identity()).unwrap();
        let with_femur: Labels = Image::from_data(grid, vec![0, 2, 7, 7]).unwrap();
        let warned = check_labels(&with_femur, path, &femur_only).unwrap();
        assert!(
            warned[0].contains("label codes 7 are not bones of the kinematic chain (2 femur)"),
            "{warned:?}"
        );
    }
}
