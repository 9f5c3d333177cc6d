//! `posereg info FILE [--json]`.

use clap::Args;
use posereg::io::nifti::describe;
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
    let description = describe(&args.file)?;
    match args.json {
        true => println!("{}", serde_json::to_string_pretty(&description)?),
        false => print!("{description}"),
    }
    Ok(())
}
