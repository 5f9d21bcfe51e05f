//! `acch bench` on a tiny configuration: it runs the three pipelines and
//! writes a report with the headline keys. No timing is asserted: a
//! benchmark reports figures.

use std::process::Command;

#[test]
fn bench_writes_the_report_keys() {
    let dir = std::env::temp_dir().join(format!("acch-bench-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("latency.json");
    let png = dir.join("latency.png");
    let out = Command::new(env!("CARGO_BIN_EXE_acch"))
        .args([
            "bench",
            "--frames",
            "20",
            "--fps",
            "30",
            "--resolution",
            "640x480",
        ])
        .arg("--json")
        .arg(&json)
        .arg("--png")
        .arg(&png)
        .env("RUST_LOG", "warn")
        .output()
        .expect("run acch bench");
    assert!(
        out.status.success(),
        "acch bench failed: {}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for key in [
        "e2e_p50_ms",
        "e2e_p99_ms",
        "hop_p99_us",
        "overhead_vs_inprocess",
        "speedup_vs_copy",
        "dropped",
    ] {
        assert!(report[key].is_number(), "no number '{key}' in {report}");
    }
    let config = &report["configs"][0];
    for mode in ["shm", "in-process", "copy"] {
        let m = &config["modes"][mode];
        let ms = |key: &str| {
            m[key]
                .as_f64()
                .unwrap_or_else(|| panic!("{mode}: no number '{key}' in {m}"))
        };
        // Percentiles of one sample, in order; each frame a result or a drop.
        assert!(
            0.0 < ms("e2e_p50_ms") && ms("e2e_p50_ms") <= ms("e2e_p90_ms"),
            "{mode}: {m}"
        );
        assert!(
            ms("e2e_p90_ms") <= ms("e2e_p99_ms") && ms("e2e_p99_ms") <= ms("e2e_max_ms"),
            "{mode}: {m}"
        );
        let count = |key: &str| m[key].as_u64().unwrap();
        assert_eq!(
            count("results") + count("dropped") + 5,
            20,
            "{mode}: 20 frames, 5 of them warm-up: {m}"
        );
        assert!(m["processes"].is_array(), "{mode}");
        // The default warm-up: the first 5 frames of the one run, apart.
        assert_eq!(config["modes"][mode]["warmup"]["frames"], 5, "{mode}");
        assert!(config["modes"][mode]["warmup"]["e2e_max_ms"].is_number());
    }
    assert!(std::fs::metadata(&png).unwrap().len() > 0);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_warmup_as_long_as_the_run_is_refused_before_anything_runs() {
    let out = Command::new(env!("CARGO_BIN_EXE_acch"))
        .args(["bench", "--frames", "5", "--warmup", "5"])
        .output()
        .expect("run acch bench");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--warmup 5") && err.contains("--frames 5"),
        "{err}"
    );
}
