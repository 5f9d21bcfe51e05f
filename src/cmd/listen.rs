//! `acch listen [KEY]`: prints what arrives on zenoh (seeds, results).

use anyhow::Result;
use clap::Args;
use std::time::{Duration, Instant};

/// Arguments of `acch listen`.
#[derive(Args)]
pub struct ListenArgs {
    /// Key expression to subscribe to.
    #[arg(default_value = "acch/**")]
    key: String,
    /// Endpoint of the pipeline's zenoh peer.
    #[arg(long, default_value = "tcp/127.0.0.1:7447")]
    connect: Vec<String>,
    /// Stop after this many samples (0 = until Ctrl-C).
    #[arg(long, default_value_t = 0)]
    count: u64,
    /// Stop after this many seconds (0 = never).
    #[arg(long, default_value_t = 0.0)]
    timeout: f64,
}

/// Runs `acch listen`.
pub fn run(args: ListenArgs) -> Result<()> {
    use zenoh::Wait;
    let session = acch_ipc::open_session(&[], &args.connect)?;
    let sub = session
        .declare_subscriber(&args.key)
        .wait()
        .map_err(|e| anyhow::anyhow!("subscribing to {}: {e}", args.key))?;
    let start = Instant::now();
    let mut n = 0;
    loop {
        if args.timeout > 0.0 && start.elapsed().as_secs_f64() > args.timeout {
            break;
        }
        match sub.recv_timeout(Duration::from_millis(200)) {
            Ok(Some(s)) => {
                println!(
                    "{}: {}",
                    s.key_expr(),
                    String::from_utf8_lossy(&s.payload().to_bytes())
                );
                n += 1;
                if args.count > 0 && n >= args.count {
                    break;
                }
            }
            Ok(None) => {}
            Err(e) => anyhow::bail!("receiving: {e}"),
        }
    }
    Ok(())
}
