//! `posereg info FILE [--json]`.

use clap::Args;
use posereg::io::nifti::read_raw;
use posereg::volume::Grid;
use std::path::PathBuf;

/// Arguments of `posereg info`.
#[derive(Args, Debug)]
pub struct InfoArgs {
    /// A .nii or .nii.gz file.
    pub file: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Prints the header and intensity range.
pub fn run(args: &InfoArgs) -> anyhow::Result<()> {
    let raw = read_raw(&args.file)?;
    let info = &raw.info;
    let dims3 = std::array::from_fn(|i| *info.header.dims.get(i).unwrap_or(&1));
    let grid = Grid::new(dims3, info.affine)
        .map_err(|e| posereg::Error::bad_file(&args.file, e.to_string()))?;
    let finite: Vec<f32> = raw.data.iter().copied().filter(|v| v.is_finite()).collect();
    let non_finite = raw.data.len() - finite.len();
    let (lo, hi) = finite
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    let affine: Vec<Vec<f64>> = (0..4)
        .map(|r| (0..4).map(|c| info.affine[(r, c)]).collect())
        .collect();
    let spacing = grid.spacing();
    if args.json {
        let value = serde_json::json!({
            "file": args.file,
            "dims": info.header.dims,
            "datatype": info.header.datatype.name(),
            "format": info.header.version,
            "byte_order": if info.header.big_endian { "big-endian" } else { "little-endian" },
            "vox_offset": info.header.vox_offset,
            "spacing": spacing,
            "pixdim": &info.header.pixdim[1..4],
            "affine": affine,
            "affine_source": info.affine_source,
            "orientation": grid.orientation_code(),
            "range": [lo, hi],
            "non_finite_voxels": non_finite,
            "scaling": info.header.scaling.map(|(slope, inter)| [slope, inter]),
            "intent_code": info.header.intent_code,
        });
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    let dims: Vec<String> = info.header.dims.iter().map(|d| d.to_string()).collect();
    println!("file:        {}", args.file.display());
    println!("dims:        {}", dims.join(" x "));
    println!(
        "datatype:    {} ({}, {})",
        info.header.datatype.name(),
        info.header.version.name(),
        if info.header.big_endian {
            "big-endian"
        } else {
            "little-endian"
        }
    );
    println!(
        "spacing:     {:.6} x {:.6} x {:.6} mm",
        spacing[0], spacing[1], spacing[2]
    );
    println!("orientation: {}", grid.orientation_code());
    println!("affine ({:?}, voxel -> world RAS mm):", info.affine_source);
    for row in &affine {
        println!(
            "  [{:>12.6} {:>12.6} {:>12.6} {:>12.6}]",
            row[0], row[1], row[2], row[3]
        );
    }
    println!("range:       {lo} .. {hi}");
    if non_finite > 0 {
        println!("non-finite:  {non_finite} voxels");
    }
    Ok(())
}
