//! Real photographs: LM-O's scene 2 (200 Kinect photos of a cluttered desk,
//! BOP format, fetched by scripts/lmo into a cache outside the clone; its
//! path in ACCH_LMO) through `acch eval --bop`, the database trained by acch
//! from the object's PLY with the dataset's recipe. Only development
//! objects are used here (1, ape; 5, can; 11, glue); 8, 9 and 12 are held
//! out.
//!
//! What is checked, each against a bound the product meets today with a
//! margin (docs/accuracy.md, "Real photographs"):
//! - with the annotated mask, few of the accepted estimates are wrong and a
//!   useful share of the instances is accepted and right;
//! - with automatic segmentation, where the colour region mostly misses the
//!   object, what is accepted is still rarely wrong;
//! - the BOP results file is read back by an independent reader
//!   (tests/bop_results_check.py, Python and NumPy against the dataset's
//!   own scene_gt.json), which must count the same accepted rows and find
//!   the same seed errors as acch's report;
//! - a symmetric object (glue, a half turn about z) is scored up to its
//!   declared symmetry;
//! - where the colours match the database strongly but wrongly (the can),
//!   the shape's better view overrules them;
//! - a database trained from the dataset's own photographs (`--train-on
//!   even`) is judged only on the others, estimates the can about as well
//!   as its mesh's, and its recognition finds the ape where the mesh's
//!   colours find the table.

mod common;

use common::{acch, ok};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// LM-O's BOP root (the folder holding `test/000002`). Fails, naming the
/// fix, when it is missing: a skipped check would pass for nothing.
fn lmo() -> PathBuf {
    let dir = std::env::var_os("ACCH_LMO").map(PathBuf::from).expect(
        "ACCH_LMO is not set: run the tests with scripts/test, which fetches LM-O (scripts/lmo)",
    );
    assert!(
        dir.join("test/000002/scene_gt.json").is_file(),
        "ACCH_LMO={} does not hold test/000002/scene_gt.json",
        dir.display()
    );
    dir
}

/// `acch eval --bop` on one object; returns the JSON report.
fn eval(dir: &Path, object: &str, segment: &str, extra: &[&str]) -> Value {
    let json = dir.join(format!("{object}-{segment}.json"));
    let root = lmo();
    let mut args = vec![
        "eval",
        "--bop",
        root.to_str().unwrap(),
        "--object",
        object,
        "--segment",
        segment,
        "--json",
        json.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = acch(&args, dir);
    ok(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("derived: visible masks"),
        "acch should say it derived the masks LM-O lacks:\n{stderr}"
    );
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

fn f(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} missing in the report"))
}

#[test]
fn ape_with_the_annotated_mask_accepts_few_wrong_and_writes_bop_results() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("ape.csv");
    let r = eval(
        dir.path(),
        "1",
        "mask",
        &["--bop-results", csv.to_str().unwrap()],
    );
    let (n, accepted, wrong) = (
        f(&r, "n"),
        f(&r, "accepted_rate"),
        f(&r, "acc_failure_rate"),
    );
    eprintln!(
        "ape, mask: {n} instances, failures {:.3}, accepted {accepted:.3}, wrong among accepted {wrong:.3}, accepted and right {:.3}",
        f(&r, "failure_rate"),
        f(&r, "accepted_right_rate")
    );
    // LM-O shows the ape in 187 images.
    assert_eq!(n, 187.0);
    // Measured 2.0 % (2 of 101); the old colour-only pipeline: 79-100 %.
    assert!(wrong <= 0.05, "wrong among accepted {wrong}");
    // Measured 52.9 % (the first round of the shape: 23 %, the fourth
    // 35.3 %); the colour-only pipeline: 0-6 %.
    assert!(
        f(&r, "accepted_right_rate") >= 0.45,
        "accepted and right {}",
        f(&r, "accepted_right_rate")
    );
    // Before acceptance: measured 27.8 % failures (the colour-only
    // pipeline: 89-100 %).
    assert!(f(&r, "failure_rate") <= 0.4);
    // The visible-share bands sum to every instance.
    let bands = r["bands"].as_array().unwrap();
    assert_eq!(bands.len(), 3);
    assert_eq!(
        bands.iter().map(|b| b["n"].as_f64().unwrap()).sum::<f64>(),
        n
    );

    // The seeds of accepted estimates: measured median 3.8° and 1.3 % of
    // the distance, 98 % within 15° and 10 %.
    let seeds = &r["seeds"];
    assert!(f(seeds, "median_rotation_err_deg") <= 10.0, "{seeds}");
    assert!(f(seeds, "median_translation_err_rel") <= 0.05, "{seeds}");
    assert!(f(seeds, "within_15deg_10pct") >= 0.8, "{seeds}");

    // The independent reader agrees with the report.
    let checked = read_back(&csv, "1", None);
    assert_eq!(
        checked["accepted"].as_f64(),
        Some(f(seeds, "n")),
        "{checked}"
    );
    assert_eq!(
        checked["accepted"].as_f64(),
        Some((accepted * n).round()),
        "every accepted estimate carries a 6-DOF pose: {checked}"
    );
    for key in ["median_rotation_err_deg", "median_translation_err_rel"] {
        let (a, b) = (f(&checked, key), f(seeds, key));
        assert!((a - b).abs() <= 1e-3 * b.max(1.0), "{key}: {a} vs {b}");
    }
}

#[test]
fn ape_with_automatic_segmentation_rejects_rather_than_accepts_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let r = eval(dir.path(), "1", "auto", &[]);
    let (accepted, wrong) = (f(&r, "accepted_rate"), f(&r, "acc_failure_rate"));
    eprintln!(
        "ape, auto: failures {:.3}, accepted {accepted:.3}, wrong among accepted {wrong:.3}",
        f(&r, "failure_rate")
    );
    // The grown colour region mostly misses the ape in this clutter
    // (measured: median share of the region on the ape 0), so few
    // estimates are right; what is accepted must still be right.
    assert!(
        median_region_on_object(&r) < 0.2,
        "{}",
        median_region_on_object(&r)
    );
    let wrongly_accepted = (wrong * accepted * f(&r, "n")).round();
    assert!(
        wrongly_accepted <= 1.0,
        "{wrongly_accepted} wrong estimates accepted"
    );
}

/// The median share of the segmented region that lies on the object.
fn median_region_on_object(r: &Value) -> f64 {
    let mut shares: Vec<f64> = r["images"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["region_on_object"].as_f64().unwrap_or(0.0))
        .collect();
    shares.sort_by(f64::total_cmp);
    shares[shares.len() / 2]
}

#[test]
fn the_apes_own_photographs_find_it_where_its_mesh_colours_do_not() {
    let dir = tempfile::tempdir().unwrap();
    let r = eval(dir.path(), "1", "auto", &["--train-on", "even"]);
    let on_object = median_region_on_object(&r);
    eprintln!(
        "ape, auto, trained on the even images: failures {:.3}, accepted and right {:.3}, median region on the ape {on_object:.2}",
        f(&r, "failure_rate"),
        f(&r, "accepted_right_rate")
    );
    // Judged only on the 103 instances in odd images, none it trained on.
    assert_eq!(f(&r, "n"), 103.0);
    // Recognition trained on real photographs finds the ape (measured:
    // median 0.64 of the region on it; from the mesh's colours, 0): the
    // gap is photometric.
    assert!(on_object >= 0.4, "{on_object}");
    // Measured 67.0 % failures (from the mesh, in the third round: 95.7 %).
    assert!(f(&r, "failure_rate") <= 0.85);
    let wrongly_accepted = (f(&r, "acc_failure_rate") * f(&r, "accepted_rate") * 103.0).round();
    assert!(wrongly_accepted <= 1.0, "{wrongly_accepted}");
}

#[test]
fn the_can_from_its_own_photographs_is_estimated_as_well_as_from_its_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let r = eval(dir.path(), "5", "mask", &["--train-on", "even"]);
    eprintln!(
        "can, mask, trained on the even images: failures {:.3}, accepted and right {:.3}, wrong among accepted {:.3}",
        f(&r, "failure_rate"),
        f(&r, "accepted_right_rate"),
        f(&r, "acc_failure_rate")
    );
    assert_eq!(f(&r, "n"), 107.0);
    // Measured 15.0 % failures, 40.2 % accepted and right, none wrong
    // (from the mesh, on the same odd images, fifth round: 23.4 %, 35.5 %,
    // none).
    assert!(f(&r, "failure_rate") <= 0.25);
    assert!(f(&r, "accepted_right_rate") >= 0.3);
    assert!(f(&r, "acc_failure_rate") <= 0.05);
}

#[test]
fn the_cans_shape_overrules_its_strong_but_wrong_colours() {
    let dir = tempfile::tempdir().unwrap();
    let r = eval(dir.path(), "5", "mask", &[]);
    let anchored_wrong = r["images"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|i| i["match_value"].as_f64().is_some_and(|m| m >= 0.65))
        .filter(|i| i["failure"] == true)
        .count();
    eprintln!(
        "can, mask: failures {:.3}, accepted and right {:.3}, {anchored_wrong} wrong among those whose colours matched at 0.65 or more",
        f(&r, "failure_rate"),
        f(&r, "accepted_right_rate")
    );
    // The can's colours match its mesh's at up to 0.96 in views half a
    // turn away. Anchored by them, 44 instances failed, all of those
    // matched at 0.65 or more, and 39.2 % of all; with the shape
    // overruling them by the acceptance margin, measured 22.6 % failures
    // and 12 of the 44 still wrong.
    assert!(f(&r, "failure_rate") <= 0.3, "{}", f(&r, "failure_rate"));
    assert!(
        anchored_wrong <= 25,
        "{anchored_wrong} strongly matched and wrong"
    );
    assert!(f(&r, "acc_failure_rate") <= 0.05);
}

#[test]
fn glue_is_scored_up_to_its_declared_half_turn() {
    let dir = tempfile::tempdir().unwrap();
    let (plain, turned) = (dir.path().join("plain"), dir.path().join("turned"));
    std::fs::create_dir_all(&plain).unwrap();
    std::fs::create_dir_all(&turned).unwrap();
    let without = eval(&plain, "11", "mask", &[]);
    let csv = turned.join("glue.csv");
    let with = eval(
        &turned,
        "11",
        "mask",
        &["--symmetry", "z:2", "--bop-results", csv.to_str().unwrap()],
    );
    let (a, b) = (f(&without, "failure_rate"), f(&with, "failure_rate"));
    eprintln!("glue, mask: failures {a:.3} without the symmetry, {b:.3} with it");
    // A glue tube turned half about its axis looks the same: scored
    // without the symmetry, right estimates count as failures (measured
    // 40.9 % against 37.0 %, 6 of 154 instances; in the fourth round 44.2
    // against 39.6 %), and the shape's margin counts the turned pose as a
    // rival, so fewer are accepted (34.4 % accepted and right against
    // 40.9 %). At least 4 instances apart:
    assert!(
        b + 4.0 / 154.0 <= a,
        "failures {b} with the symmetry, {a} without"
    );
    let (right_without, right_with) = (
        f(&without, "accepted_right_rate"),
        f(&with, "accepted_right_rate"),
    );
    assert!(
        right_without < right_with,
        "accepted and right {right_with} with the symmetry, {right_without} without"
    );
    // Measured 0 of 63 wrong among accepted with it (2 of 60 in the fifth
    // round; with the sixth round's finer polish and without its bar on
    // low views, 4 of 67).
    assert!(f(&with, "acc_failure_rate") <= 0.05);
    // The independent reader, allowing the half turn, finds the seeds'
    // errors acch reports.
    let checked = read_back(&csv, "11", Some("z:2"));
    let seeds = &with["seeds"];
    assert_eq!(
        checked["accepted"].as_f64(),
        Some(f(seeds, "n")),
        "{checked}"
    );
    let (a, b) = (
        f(&checked, "median_rotation_err_deg"),
        f(seeds, "median_rotation_err_deg"),
    );
    assert!((a - b).abs() <= 1e-2, "median rotation error {a} vs {b}");
}

/// tests/bop_results_check.py on a results file; its JSON line.
fn read_back(csv: &Path, object: &str, symmetry: Option<&str>) -> Value {
    let gt = lmo().join("test/000002/scene_gt.json");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bop_results_check.py");
    let mut cmd = Command::new("python3");
    cmd.arg(script).arg(csv).arg(gt).arg(object);
    if let Some(s) = symmetry {
        cmd.arg(s);
    }
    let out = cmd
        .output()
        .expect("python3 with numpy (scripts/test installs it)");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "bop_results_check.py refused the file: {stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(stdout.trim()).unwrap()
}
