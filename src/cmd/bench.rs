//! `acch bench`: the latency benchmark ([`acch_bench`]), measuring this
//! executable's own `acch run`.

use anyhow::{Context, Result};
use clap::Args;

/// Arguments of `acch bench`.
#[derive(Args)]
pub struct BenchArgs {
    #[command(flatten)]
    bench: acch_bench::BenchArgs,
}

/// Runs `acch bench`.
pub fn run(args: BenchArgs) -> Result<()> {
    let mut bench = args.bench;
    bench.exe = std::env::current_exe().context("locating the acch executable")?;
    Ok(acch_bench::run(bench)?)
}
