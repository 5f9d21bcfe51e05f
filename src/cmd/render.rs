//! `acch render` (placeholder until the renderer lands).
use clap::Args;

/// Arguments of `acch render`.
#[derive(Args)]
pub struct RenderArgs {}

/// Runs `acch render`.
pub fn run(_args: RenderArgs) -> anyhow::Result<()> {
    anyhow::bail!("not yet implemented")
}
