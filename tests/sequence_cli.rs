//! `acch eval --protocol sequence` end to end on a small budget: trains the
//! can (fewer confidence scenes), runs short trajectories (θ sweeping the
//! default [20, 90]) and a few re-view episodes per background, and checks
//! the report: its keys, consistent counts (failures = no answer + wrong,
//! fused no-answer = frames before the filter's start), and that on the easy
//! background the fused pose tracks the truth once started.

use std::process::Command;

fn acch(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_acch"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .expect("run acch")
}

#[test]
fn sequence_protocol_reports_single_vs_fused_and_review() {
    let dir = std::env::temp_dir().join(format!("acch-sequence-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let json = dir.join("sequence.json");
    let out = acch(&[
        "eval",
        "--protocol",
        "sequence",
        "--object",
        "can",
        "--trajectories",
        "2",
        "--frames",
        "12",
        "--n",
        "4",
        "--max-moves",
        "3",
        "--confidence-scenes",
        "15",
        "--json",
        json.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "acch eval failed: {stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("re-view"), "{stdout}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["protocol"], "sequence");
    let rows = report["rows"].as_array().unwrap();
    let names: Vec<&str> = rows
        .iter()
        .map(|r| r["background"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["A", "B", "C", "clutter"]);
    for r in rows {
        assert_eq!(r["frames"], 24, "{r}");
        for key in [
            "single_failure_rate",
            "single_no_answer_rate",
            "single_wrong_rate",
            "raw_failure_rate",
            "fused_failure_rate",
            "fused_no_answer_rate",
            "fused_wrong_rate",
        ] {
            // A share of the episode's 24 frames: a whole number of them.
            let x = r[key].as_f64().unwrap_or(f64::NAN) * 24.0;
            assert!((x - x.round()).abs() < 1e-6, "{key} = {x}/24 in {r}");
        }
        for key in ["single_mean_phi_err_deg", "fused_mean_phi_err_deg"] {
            let x = r[key].as_f64().unwrap_or(f64::NAN);
            assert!((0.0..=180.0).contains(&x), "{key} = {x} in {r}");
        }
        let f = |key: &str| r[key].as_f64().unwrap();
        let u = |key: &str| r[key].as_u64().unwrap();
        // A failure is either no answer or a wrong one, for both outcomes.
        for who in ["single", "fused"] {
            let parts = f(&format!("{who}_no_answer_rate")) + f(&format!("{who}_wrong_rate"));
            assert!(
                (f(&format!("{who}_failure_rate")) - parts).abs() < 1e-9,
                "{who}: {r}"
            );
        }
        // Fused no-answer frames are exactly those before the filter's start.
        let no_fused = (f("fused_no_answer_rate") * 24.0).round() as u64;
        assert_eq!(no_fused + u("started_frames"), 24, "{r}");
        // Single frames without an answer were not found or rejected.
        let no_single = (f("single_no_answer_rate") * 24.0).round() as u64;
        assert_eq!(
            no_single,
            u("single_not_found") + u("single_rejected"),
            "{r}"
        );
        assert!(u("below_database_frames") <= 24, "{r}");
        // Every accepted estimate was either fused, gated or restarted the filter.
        let accepted = 24 - no_single;
        let used = r["fused_updates"].as_u64().unwrap()
            + r["gated"].as_u64().unwrap()
            + r["reinitialised"].as_u64().unwrap();
        assert_eq!(accepted, used, "{r}");
    }
    // The can on wood grain is easy: once started, the filter tracks.
    let a = &rows[0];
    assert!(a["started_frames"].as_u64().unwrap() > 0, "{a}");
    assert!(
        a["fused_answer_failure_rate"].as_f64().unwrap() <= 0.1,
        "{a}"
    );
    assert!(a["fused_mean_phi_err_deg"].as_f64().unwrap() < 5.0, "{a}");
    assert!(a["fused_mean_theta_err_deg"].as_f64().unwrap() < 5.0, "{a}");

    let review = report["review"].as_array().unwrap();
    assert_eq!(review.len(), 8, "4 backgrounds x 2 policies");
    for r in review {
        let n = r["episodes"].as_u64().unwrap();
        assert_eq!(n, 4);
        let parts = r["initially_rejected"].as_u64().unwrap()
            + r["initially_correct"].as_u64().unwrap()
            + r["initially_wrong"].as_u64().unwrap();
        assert_eq!(parts, n, "{r}");
        assert!(r["max_moves"].as_u64().unwrap() <= 3, "{r}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sequence_protocol_rejects_an_empty_budget() {
    let out = acch(&[
        "eval",
        "--protocol",
        "sequence",
        "--object",
        "can",
        "--frames",
        "0",
    ]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--frames"), "{stderr}");
}

#[test]
fn sequence_protocol_rejects_a_bad_elevation_band() {
    let out = acch(&[
        "eval",
        "--protocol",
        "sequence",
        "--object",
        "can",
        "--theta-min",
        "60",
        "--theta-max",
        "50",
    ]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--theta-min 60"), "{stderr}");
}
