//! `acch stage NAME --config FILE`: one stage of the pipeline as a process
//! (started by `acch run`; can be started by hand with the same config).

use crate::stages::{self, PipelineConfig};
use acch_ipc::{Observer, StageId};
use anyhow::{Result, anyhow};
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
    let cfg = PipelineConfig::load(&args.config)?;
    if let Some(o) = Observer::from_name(&args.name) {
        return match o {
            Observer::Viz => super::viz::run(&cfg),
            Observer::Record => super::record::run(&cfg),
        };
    }
    let id =
        StageId::from_name(&args.name).ok_or_else(|| anyhow!("unknown stage '{}'", args.name))?;
    let (w, h) = stages::frame_size(&cfg)?;
    match id {
        StageId::Capture => stages::run_capture(&cfg),
        StageId::Recognition => stages::run_stage(&cfg, stages::Recognition::new(&cfg, w, h)?),
        StageId::Segmentation => stages::run_stage(&cfg, stages::Segmentation::new(&cfg, w, h)?),
        StageId::Pose => stages::run_stage(&cfg, stages::Pose::new(&cfg, w, h)?),
        StageId::Confidence => stages::run_stage(&cfg, stages::Confidence::new(&cfg)?),
        StageId::Seeding => stages::run_stage(&cfg, stages::Seeding::new(&cfg)?),
    }
}
