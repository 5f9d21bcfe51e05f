//! An unrated estimate is never accepted: `acch run` refuses a database
//! without a confidence network, naming the way out, and with `--unrated`
//! it runs and reports every estimate as unrated, accepting and seeding
//! none, in both executors.

mod common;

use common::{free_port, summary};
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

fn acch(dir: &Path, args: &[&str]) -> Output {
    let config = dir.join("zenoh.toml");
    std::fs::write(
        &config,
        format!("[zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\n", free_port()),
    )
    .unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_acch"));
    cmd.args(args);
    if args.first() == Some(&"run") {
        cmd.arg("--config").arg(&config);
    }
    cmd.output().unwrap()
}

#[test]
fn a_database_without_a_network_is_refused_or_runs_explicitly_unrated() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("no-network.acchdb");
    let out = acch(
        dir.path(),
        &[
            "train",
            "--object",
            "fruitbox",
            "--views",
            "grid:50,70,90:30",
            "--confidence-scenes",
            "0",
            "--out",
            db.to_str().unwrap(),
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let db = db.to_str().unwrap();

    let out = acch(dir.path(), &["run", "--db", db, "--frames", "10"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "a database without a network ran rated: {err}"
    );
    assert!(
        err.contains("no confidence network") && err.contains("--unrated"),
        "the refusal does not say why or what to do: {err}"
    );

    for in_process in [false, true] {
        let json = dir.path().join("run.json");
        let results = dir.path().join("results.jsonl");
        let mut args = vec![
            "run",
            "--db",
            db,
            "--frames",
            "30",
            "--unrated",
            "--json",
            json.to_str().unwrap(),
            "--results",
            results.to_str().unwrap(),
        ];
        if in_process {
            args.push("--in-process");
        }
        let out = acch(dir.path(), &args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert!(
            err.contains("UNRATED"),
            "the unrated mode is not visible: {err}"
        );
        let s = summary(&json);
        assert_eq!(s["unrated"], true, "{s}");
        assert!(s["estimated"].as_u64().unwrap() >= 20, "{s}");
        assert_eq!(s["unrated_estimates"], s["estimated"], "{s}");
        assert_eq!(s["accepted"], 0, "unrated estimates were accepted: {s}");
        assert_eq!(s["seeds"], 0, "{s}");
        let lines: Vec<Value> = std::fs::read_to_string(&results)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len(), 30);
        for r in &lines {
            assert_eq!(r["accepted"], false, "{r}");
            assert!(r["seed"].is_null(), "{r}");
            if r["estimate_deg"].is_array() {
                assert_eq!(r["rating"], "unrated", "{r}");
                assert!(r["confidence"].is_null(), "{r}");
            }
        }
    }
}
