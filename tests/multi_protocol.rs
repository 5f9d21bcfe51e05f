//! `acch eval --protocol multi`: scenes of several known objects with
//! ground truth per object. With fruitbox and can both known and both in
//! view, each is found where it stands and rarely taken for the other,
//! the figures with both known stay near those of each object alone on
//! the same scenes, and the report's counts agree with each other.

mod common;

use common::{acch, ok};
use serde_json::Value;

#[test]
fn two_known_objects_are_found_and_told_apart() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("multi.json");
    let errors = dir.path().join("multi.csv");
    let stdout = ok(&acch(
        &[
            "eval",
            "--protocol",
            "multi",
            "--objects",
            "fruitbox,can",
            "--in-view",
            "2",
            "--n",
            "8",
            "--seed",
            "11",
            "--json",
            json.to_str().unwrap(),
            "--errors",
            errors.to_str().unwrap(),
        ],
        dir.path(),
    ));
    eprintln!("{stdout}");
    // Every detection cleared its threshold; every estimate accepted was
    // rated, its rival within the rule's bound, not faint and weak.
    let csv = std::fs::read_to_string(&errors).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (detected, accepted) = (col("detected"), col("accepted"));
    let (margin, confidence, rival) = (col("score_margin"), col("confidence"), col("rival"));
    let match_value = col("match_value");
    let (mut detections, mut accepts) = (0, 0);
    for line in lines {
        let v: Vec<&str> = line.split(',').collect();
        let num = |i: usize| v[i].parse::<f64>().unwrap_or(f64::NAN);
        if v[detected] == "1" {
            detections += 1;
            // Found from recognition's floor, a fraction of the threshold.
            assert!(
                num(margin) >= acch_recognition::MIN_FOUND_MARGIN as f64 - 5e-4,
                "{line}"
            );
        } else {
            assert!(v[margin].is_empty(), "{line}");
        }
        if v[accepted] == "1" {
            accepts += 1;
            // Never accepted under the threshold itself.
            assert!(
                num(margin) >= acch_confidence::MIN_ACCEPTED_DETECTION_MARGIN as f64 - 5e-4,
                "{line}"
            );
            assert!((0.0..=1.0).contains(&num(confidence)), "{line}");
            assert!(
                num(rival) <= acch_confidence::MAX_RIVAL_RATIO as f64,
                "{line}"
            );
            assert!(
                !acch_confidence::rejected_as_faint(
                    num(margin) as f32 + 5e-4,
                    num(match_value) as f32 + 5e-4
                ),
                "{line}"
            );
        }
    }
    assert!(
        detections > 0 && accepts > 0,
        "{detections} detections, {accepts} accepted"
    );
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 6, "3 backgrounds x 2 objects");
    let f = |r: &Value, k: &str| r[k].as_f64().unwrap();
    for name in ["fruitbox", "can"] {
        let mine: Vec<&Value> = rows.iter().filter(|r| r["object"] == name).collect();
        let sum = |k: &str| mine.iter().map(|r| r[k].as_u64().unwrap()).sum::<u64>();
        let (in_view, detections) = (sum("in_view"), sum("detections"));
        assert!(in_view >= 12, "{name}: only {in_view} clear appearances");
        let found: f64 = mine.iter().map(|r| f(r, "recall") * f(r, "in_view")).sum();
        assert!(
            found >= 0.75 * in_view as f64,
            "{name}: found {found} of {in_view}"
        );
        let right: f64 = mine
            .iter()
            .map(|r| f(r, "precision") * f(r, "detections"))
            .sum();
        assert!(
            right >= 0.8 * detections as f64,
            "{name}: {right} of {detections} right"
        );
        for r in &mine {
            // Both known against alone, on the same scenes.
            let single = &r["single"];
            assert!(f(r, "recall") >= f(single, "recall") - 0.25, "{r}");
            assert!(
                f(r, "acc_failure_rate") <= f(single, "acc_failure_rate") + 0.2,
                "{r}"
            );
        }
    }
    // A confusion is a wrong detection: never more than the detections
    // that were not right.
    for c in report["confusions"].as_array().unwrap() {
        let row = rows
            .iter()
            .find(|r| r["background"] == c["background"] && r["object"] == c["detected_as"])
            .unwrap();
        let wrong = f(row, "detections") * (1.0 - f(row, "precision"));
        assert!(c["count"].as_f64().unwrap() <= wrong + 1e-9, "{c} vs {row}");
    }
}

#[test]
fn the_protocol_names_what_it_cannot_measure() {
    let dir = tempfile::tempdir().unwrap();
    for (args, says) in [
        (
            vec!["--objects", "fruitbox,can", "--in-view", "3"],
            "--in-view 3",
        ),
        (vec![], "--objects"),
    ] {
        let mut all = vec!["eval", "--protocol", "multi", "--n", "1"];
        all.extend(args);
        let out = acch(&all, dir.path());
        assert!(!out.status.success(), "{all:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{all:?}: {err}");
    }
}
