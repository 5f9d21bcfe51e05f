//! The camera rolls: over a simulated eye-in-hand run whose camera rolls
//! within ±40°, the pose stage's roll search keeps the seeds' full
//! rotation within 10° of the truth; without it the same frames' seeds are
//! off, so the check can fail.

mod common;

use common::free_port;
use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// Accepted seeds with their rotation error against the truth, degrees,
/// and their roll error where the roll is a rotation of its own (θ <= 70°:
/// towards the top view a roll and a turn in φ become the same rotation,
/// so the roll alone is not defined there), of a 300-frame run.
fn run(dir: &Path, camera_roll: f64, search: f64) -> Vec<(f64, Option<f64>)> {
    let config = dir.join(format!("r{camera_roll}-{search}.toml"));
    std::fs::write(
        &config,
        format!(
            "frames = 300\nfps = 0.0\nseed = 11\nelevation_deg = [45.5, 70.0]\n\
             camera_roll_deg = {camera_roll}\n\
             roll_search_deg = {search}\n[zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\n",
            free_port()
        ),
    )
    .unwrap();
    let results = dir.join("results.jsonl");
    let out = Command::new(env!("CARGO_BIN_EXE_acch"))
        .args(["run", "--in-process", "--config"])
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
    std::fs::read_to_string(&results)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .filter(|r| r["accepted"] == true)
        .map(|r| {
            let q = |v: &Value| -> [f64; 4] {
                let a = v.as_array().unwrap();
                [0, 1, 2, 3].map(|i| a[i].as_f64().unwrap())
            };
            let (s, t) = (
                q(&r["seed"]["rotation_xyzw"]),
                q(&r["truth"]["rotation_xyzw"]),
            );
            let dot: f64 = (0..4).map(|i| s[i] * t[i]).sum::<f64>().abs().min(1.0);
            let roll = r["roll_deg"].as_f64().unwrap() - r["truth"]["roll_deg"].as_f64().unwrap();
            let theta = r["truth"]["theta_deg"].as_f64().unwrap();
            (
                2.0 * dot.acos().to_degrees(),
                (theta <= 70.0).then(|| (roll + 180.0).rem_euclid(360.0) - 180.0),
            )
        })
        .collect()
}

#[test]
fn the_roll_search_keeps_a_rolling_cameras_seeds_right() {
    let dir = tempfile::tempdir().unwrap();
    let within = |v: &[(f64, Option<f64>)]| {
        v.iter().filter(|(e, _)| *e <= 10.0).count() as f64 / v.len() as f64
    };
    let searched = run(dir.path(), 40.0, 45.0);
    assert!(
        searched.len() >= 240,
        "only {} of 300 accepted",
        searched.len()
    );
    let share = within(&searched);
    let rolls: Vec<f64> = searched
        .iter()
        .filter_map(|(_, r)| r.map(f64::abs))
        .collect();
    assert!(rolls.len() >= 20, "only {} frames at θ <= 70°", rolls.len());
    let roll_err = rolls.iter().sum::<f64>() / rolls.len() as f64;
    eprintln!(
        "roll search on: {} accepted, {:.1} % within 10°, mean roll error {roll_err:.2}° \
         over {} at θ <= 70°",
        searched.len(),
        100.0 * share,
        rolls.len()
    );
    assert!(share >= 0.95, "{:.1} % of seeds within 10°", 100.0 * share);
    assert!(roll_err <= 6.0, "mean roll error {roll_err:.2}°");
    // The same frames without the search: the roll is missing from the
    // seeds.
    let upright = run(dir.path(), 40.0, 0.0);
    let missing: Vec<f64> = upright
        .iter()
        .filter_map(|(_, r)| r.map(f64::abs))
        .collect();
    let roll_err_upright = missing.iter().sum::<f64>() / missing.len().max(1) as f64;
    eprintln!(
        "roll search off: {:.1} % within 10°, mean roll error {roll_err_upright:.2}°",
        100.0 * within(&upright)
    );
    assert!(
        roll_err_upright > 2.0 * roll_err,
        "without the search the roll error is {roll_err_upright:.2}°, with it {roll_err:.2}°"
    );
}
