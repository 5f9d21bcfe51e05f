//! `acch`: train view databases, estimate 2-DOF poses, evaluate, and run the pipeline.

mod cmd;

use clap::{Parser, Subcommand};

/// Real-time 2-DOF pose estimation of textured objects with angular colour
/// cooccurrence histograms (ACCH).
#[derive(Parser)]
#[command(name = "acch", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render views of an object with ground truth (images, masks, labels.csv).
    Render(cmd::render::RenderArgs),
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => cmd::render::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
