//! An unrated estimate is never accepted: a database without a confidence
//! network runs when it holds its object's shape (the shape judges the
//! estimates it chose; the rest are unrated); `acch run`
//! refuses a database with neither, naming the way out, and with
//! `--unrated` it runs and reports every estimate as unrated, accepting
//! and seeding none, in both executors.

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

    // With the mesh's shape, the shape judges: the run is rated.
    let json = dir.path().join("shape.json");
    let out = acch(
        dir.path(),
        &[
            "run",
            "--db",
            db.to_str().unwrap(),
            "--frames",
            "10",
            "--json",
            json.to_str().unwrap(),
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Not refused and not unrated as a run; an estimate the shape chose is
    // judged by it, one the colours anchored needs the network this
    // database lacks and is reported unrated (here all 10: the printed
    // box's colours place every view).
    let s = summary(&json);
    assert_eq!(s["unrated"], false, "{s}");
    let n = |k: &str| s[k].as_u64().unwrap();
    assert_eq!(
        n("accepted") + n("rejected") + n("unrated_estimates"),
        n("estimated"),
        "{s}"
    );
    assert!(n("estimated") >= 8, "{s}");
    assert_eq!(n("seeds"), n("accepted"), "{s}");

    // Neither a network nor a shape: refused.
    let mut stripped = acch_core::ViewDatabase::load(&db).unwrap();
    assert!(
        stripped
            .sections
            .remove(acch_shape::SHAPE_SECTION)
            .is_some(),
        "a database trained from an object holds its shape"
    );
    stripped.sections.remove(acch_shape::SYMMETRY_SECTION);
    let db = dir.path().join("neither.acchdb");
    stripped.save(&db).unwrap();
    let db = db.to_str().unwrap();

    let out = acch(dir.path(), &["run", "--db", db, "--frames", "10"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "a database without a network or a shape ran rated: {err}"
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
