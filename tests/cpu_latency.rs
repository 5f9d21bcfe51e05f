//! `acch run --cpu-latency-us`: the launcher holds the kernel's CPU latency
//! request for as long as the run lasts, and the kernel's own file shows it;
//! where the file cannot be written the run refuses at once, saying why.

mod common;

use acch_ipc::sched::CpuLatencyRequest;
use common::summary;
use std::io::Read;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The bound in force now, µs.
fn in_force() -> u32 {
    CpuLatencyRequest::in_force().expect("read the kernel's CPU latency")
}

#[test]
fn a_run_holds_the_cpu_latency_it_is_given_while_it_lasts() {
    // Opening for writing adds an unconstrained request: a probe of the
    // permission that changes nothing.
    let writable = std::fs::OpenOptions::new()
        .write(true)
        .open(CpuLatencyRequest::PATH)
        .is_ok();
    let dir = std::env::temp_dir().join(format!("acch-cpu-latency-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("run.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_acch"))
        .args([
            "run",
            "--frames",
            "45",
            "--fps",
            "30",
            "--cpu-latency-us",
            "7",
        ])
        .arg("--json")
        .arg(&json)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start acch run");
    if !writable {
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert!(
            err.contains("cpu_latency_us = 7") && err.contains("root"),
            "{err}"
        );
        return;
    }
    let before = in_force();
    // The tightest request held while the run lasts, read from the kernel.
    let mut tightest = u32::MAX;
    let deadline = Instant::now() + Duration::from_secs(120);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(Instant::now() < deadline, "acch run did not finish");
        tightest = tightest.min(in_force());
        std::thread::sleep(Duration::from_millis(5));
    };
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    assert!(status.success(), "acch run failed: {err}");
    assert_eq!(tightest, before.min(7), "the request was not in force");
    // Released with the launcher.
    assert_eq!(in_force(), before);
    let summary = summary(&json);
    assert_eq!(summary["cpu_latency_us"], 7);
    // The run itself went on: nearly every frame delivered (a count with
    // room for a loaded machine, not a timing).
    let results = summary["results"].as_u64().unwrap();
    assert!(results >= 40, "{results} of 45 frames delivered: {summary}");
    let _ = std::fs::remove_dir_all(&dir);
}
