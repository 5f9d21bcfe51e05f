//! `acch run --mesh FILE.obj` runs the simulated scene over that mesh, not
//! the built-in default: results go by the mesh's name and its estimates
//! are of its views (the duck's database is trained and cached for it).

mod common;

use common::free_port;
use serde_json::Value;
use std::process::Command;

#[test]
fn run_over_a_mesh_estimates_that_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("p.toml");
    std::fs::write(
        &config,
        format!("[zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\n", free_port()),
    )
    .unwrap();
    let results = dir.path().join("r.jsonl");
    // The shared duck, as tests/render_cli.rs reads it.
    let mesh = "/work/shared/data/duck/duck.obj";
    let out = Command::new(env!("CARGO_BIN_EXE_acch"))
        .args([
            "run",
            "--in-process",
            "--frames",
            "30",
            "--fps",
            "0",
            "--mesh",
            mesh,
        ])
        // Its file in units of 5 cm: the scene and the seeds in metres of it.
        .args(["--mesh-unit-m", "0.05"])
        .arg("--config")
        .arg(&config)
        .arg("--results")
        .arg(&results)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: Vec<Value> = std::fs::read_to_string(&results)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(rows.len(), 30);
    assert!(rows.iter().all(|r| r["object"] == "duck"), "{}", rows[0]);
    // The camera flies at 5 bounding radii: the duck's (about one file
    // unit, 5 cm here), not the fruitbox's 0.206 m.
    let d = rows[0]["truth"]["distance"].as_f64().unwrap();
    assert!(
        (0.15..0.35).contains(&d),
        "camera {d} m away: not the duck's scene"
    );
    let accepted = rows.iter().filter(|r| r["accepted"] == true).count();
    assert!(accepted >= 25, "only {accepted} of 30 accepted");
}
