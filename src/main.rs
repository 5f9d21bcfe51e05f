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
    /// Stream frames through every stage (default: built-in fruitbox, simulated camera).
    Run(Box<cmd::run::RunArgs>),
    /// One stage of the pipeline as a process (started by `acch run`).
    Stage(cmd::stage::StageArgs),
    /// Print what arrives on zenoh (seeds, results).
    Listen(cmd::listen::ListenArgs),
    /// Render views of an object with ground truth (images, masks, labels.csv).
    Render(cmd::render::RenderArgs),
    /// Train a view database from a rendered object or labelled images.
    Train(cmd::train::TrainArgs),
    /// Estimate the 2-DOF pose of the object in an image.
    Estimate(cmd::estimate::EstimateArgs),
    /// Write an image's histogram as a NumPy .npy array.
    Features(cmd::features::FeaturesArgs),
    /// Evaluate accuracy with a reproducible protocol (paper table 1).
    Eval(Box<cmd::eval::EvalArgs>),
    /// Latency benchmark: processes vs one process vs frames copied (JSON + PNG).
    Bench(cmd::bench::BenchArgs),
}

fn main() -> std::process::ExitCode {
    restore_sigpipe();
    acch_ipc::quiet_iceoryx2_logs();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info,zenoh=error")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run(args) => cmd::run::run(*args),
        Command::Bench(args) => cmd::bench::run(args),
        Command::Render(args) => cmd::render::run(args),
        Command::Stage(args) => cmd::stage::run(args),
        Command::Listen(args) => cmd::listen::run(args),
        Command::Train(args) => cmd::train::run(args),
        Command::Eval(args) => cmd::eval::run(*args),
        Command::Estimate(args) => cmd::estimate::run(args),
        Command::Features(args) => cmd::features::run(args),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {}", each_cause_once(&err));
            std::process::ExitCode::FAILURE
        }
    }
}

/// The error and its causes joined by ": ", each said once: a library
/// error whose message already holds its source (`"{path}: {source}"`)
/// would otherwise print that source again as the next cause.
fn each_cause_once(err: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in err.chain() {
        let said = cause.to_string();
        if !text.contains(&said) {
            if !text.is_empty() {
                text.push_str(": ");
            }
            text.push_str(&said);
        }
    }
    text
}

/// Rust ignores SIGPIPE, so printing into a closed pipe (`acch ... | head`)
/// would panic; a command-line tool should end quietly instead.
fn restore_sigpipe() {
    // SAFETY: called first thing in main, before any thread exists; it only
    // resets the signal's disposition to the default.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
