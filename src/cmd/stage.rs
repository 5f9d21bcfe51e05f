//! `acch stage NAME --config FILE`: one process of the pipeline (started by
//! `acch run`; can be started by hand with the same configuration).

use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

/// Arguments of `acch stage`.
#[derive(Args)]
pub struct StageArgs {
    /// capture, recognition, segmentation, pose, confidence or seeding; or
    /// an observer: viz (rerun) or record (MCAP).
    name: String,
    /// Pipeline configuration (TOML), the one the launcher wrote.
    #[arg(long, value_name = "FILE")]
    config: PathBuf,
}

/// Runs `acch stage`.
pub fn run(args: StageArgs) -> Result<()> {
    Ok(acch_pipeline::run_process(&args.name, &args.config)?)
}
