//! Scaffolding shared by the integration tests that start `acch`: free
//! loopback ports, a guard that stops a launched pipeline however the test
//! ends, and the run summary.

// Each test binary compiles this module and uses a part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// A TCP port on loopback that nothing listens on now (zenoh's).
pub fn free_port() -> u16 {
    free_ports::<1>()[0]
}

/// `N` distinct such ports: each is held until all are picked, since a port
/// just let go may be handed out again (two sessions of one test then
/// listened on the same port: "Address already in use").
pub fn free_ports<const N: usize>() -> [u16; N] {
    let held: [std::net::TcpListener; N] =
        std::array::from_fn(|_| std::net::TcpListener::bind("127.0.0.1:0").unwrap());
    held.map(|l| l.local_addr().unwrap().port())
}

/// Stops the launcher on drop, as a user's Ctrl-C would (its children stop
/// with it); killed if it has not exited within 8 s. A failing test leaves
/// no process behind.
pub struct Guard(pub Child);

impl Drop for Guard {
    fn drop(&mut self) {
        // SAFETY: kill(2) on our own child.
        unsafe { libc::kill(self.0.id() as i32, libc::SIGINT) };
        let until = Instant::now() + Duration::from_secs(8);
        while Instant::now() < until {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A run's JSON summary (`acch run --json`).
pub fn summary(json: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

/// A configuration in `dir` that keeps zenoh on a free loopback port.
pub fn loopback_config(dir: &Path) -> PathBuf {
    let p = dir.join("pipeline.toml");
    std::fs::write(
        &p,
        format!("[zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\n", free_port()),
    )
    .unwrap();
    p
}

/// Pipelines share 2 cores: one at a time, or several pipelines' stages on
/// the one stage CPU stall each other until frames overflow their queues.
static SERIAL: Mutex<()> = Mutex::new(());

/// `acch run ARGS` on a loopback configuration in `dir`, one at a time per
/// test binary, with a 15 s stall timeout; its stderr is echoed for the
/// test log.
pub fn acch_run(dir: &Path, args: &[&str]) -> Output {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let out = Command::new(env!("CARGO_BIN_EXE_acch"))
        .arg("run")
        .arg("--config")
        .arg(loopback_config(dir))
        .args(["--stall-timeout", "15"])
        .args(args)
        .output()
        .unwrap();
    eprintln!(
        "acch run {}:\n{}",
        args.join(" "),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// `acch ARGS` in `cwd`, quiet below warnings.
pub fn acch(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_acch"))
        .args(args)
        .current_dir(cwd)
        .env("RUST_LOG", "warn")
        .output()
        .expect("run acch")
}

/// The stdout of a command that must have succeeded (else its output is
/// the failure message).
pub fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "failed: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The report lines of an independent zenoh subscriber
/// (tests/pipeline_subscriber.py, Python `eclipse-zenoh`).
pub type Reports = std::io::Lines<std::io::BufReader<std::process::ChildStdout>>;

/// Starts tests/pipeline_subscriber.py listening on loopback `port` for
/// `frames` results of `object` (at most 240 s), and waits until it is
/// ready; the pipeline then connects to it. Its report is the next line.
pub fn zenoh_subscriber(object: &str, port: u16, frames: u64) -> (Guard, Reports) {
    use std::io::BufRead;
    let mut sub = Guard(
        Command::new("python3")
            .arg(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/tests/pipeline_subscriber.py"
            ))
            .arg(format!("tcp/127.0.0.1:{port}"))
            .arg(object)
            .arg(frames.to_string())
            .arg("240")
            .stdout(std::process::Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let mut lines = std::io::BufReader::new(sub.0.stdout.take().unwrap()).lines();
    let ready = lines.next().unwrap().unwrap();
    assert!(ready.contains("ready"), "{ready}");
    (sub, lines)
}
