//! The `posereg` command: parse, call the library, exit non-zero with one line on failure.

mod cli;

use clap::Parser;

fn main() {
    let parsed = cli::Cli::parse();
    if let Err(e) = cli::run(parsed) {
        eprintln!("posereg: error: {e:#}");
        std::process::exit(1);
    }
}
