//! `posereg eval --field F --truth T [--mask M] [--warped W --target I] [--json]`: the paper's
//! figures for an estimated field against a true one.

use clap::Args;
use posereg::images::metric::correlation;
use posereg::io::field::load_field;
use posereg::io::nifti::{load_labels, load_volume};
use posereg::report::evaluate::field_error;
use posereg::Error;
use std::path::PathBuf;

/// Arguments of `posereg eval`.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Estimated displacement field (ITK convention).
    #[arg(long)]
    pub field: PathBuf,
    /// True displacement field on the same grid.
    #[arg(long)]
    pub truth: PathBuf,
    /// Label map on the same grid: voxels with a non-zero label are evaluated (default: all).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Registered image, for the correlation after (with --target).
    #[arg(long, requires = "target")]
    pub warped: Option<PathBuf>,
    /// Target image, for the correlation.
    #[arg(long, requires = "warped")]
    pub target: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Prints mean error, median, 95th percentile, shares within 2 and 4 voxels, correlation.
pub fn run(args: &EvalArgs) -> anyhow::Result<()> {
    let estimate = load_field(&args.field)?;
    let truth = load_field(&args.truth)?;
    if !truth.grid.same_as(&estimate.grid, 1e-3) {
        return Err(Error::bad_file(
            &args.truth,
            format!("grid differs from {}", args.field.display()),
        )
        .into());
    }
    let mask = match &args.mask {
        Some(path) => {
            let labels = load_labels(path)?;
            if !labels.grid.same_as(&estimate.grid, 1e-3) {
                return Err(Error::bad_file(path, "mask is not on the fields' grid").into());
            }
            labels.data.iter().map(|&l| l != 0).collect()
        }
        None => vec![true; estimate.grid.len()],
    };
    let e = field_error(&estimate, &truth, |n| mask[n]).map_err(|err| match &args.mask {
        Some(path) => Error::bad_file(path, err.to_string()),
        None => err,
    })?;
    let r = match (&args.warped, &args.target) {
        (Some(w), Some(t)) => {
            let on_grid = |path: &PathBuf| -> anyhow::Result<posereg::Volume> {
                let volume = load_volume(path)?;
                if !volume.grid.same_as(&estimate.grid, 1e-3) {
                    let problem = format!("is not on the grid of {}", args.field.display());
                    return Err(Error::bad_file(path, problem).into());
                }
                Ok(volume)
            };
            let (w, t) = (on_grid(w)?, on_grid(t)?);
            Some(correlation(&w.data, &t.data, |n| mask[n]))
        }
        _ => None,
    };
    if args.json {
        let mut v = serde_json::to_value(&e)?;
        v["correlation"] = serde_json::json!(r);
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!("voxels:            {}", e.voxels);
        println!(
            "mean error:        {:.3} mm (median {:.3}, 95th percentile {:.3})",
            e.mean_mm, e.median_mm, e.p95_mm
        );
        println!("within 2 voxels:   {:.2}%", 100.0 * e.within_2_voxels);
        println!("within 4 voxels:   {:.2}%", 100.0 * e.within_4_voxels);
        if let Some(r) = r {
            println!("correlation:       {r:.4}");
        }
    }
    Ok(())
}
