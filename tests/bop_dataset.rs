//! BOP datasets in and out: a scene `acch render --format bop` writes reads
//! back through `acch eval --bop` with the very figures `acch eval
//! --labels` gives on the same views; an independent reader of the BOP
//! spec (tests/bop_check.py) accepts the files; bad datasets are refused
//! naming the file.

mod common;

use common::{acch, ok};
use std::path::Path;
use std::process::{Command, Output};

fn failed(out: &Output) -> String {
    assert!(!out.status.success(), "acch should have failed");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn render(d: &Path, out: &str, extra: &[&str]) {
    let mut args = vec![
        "render",
        "--object",
        "can",
        "--background",
        "A",
        "--views",
        "random:24",
        "--seed",
        "5",
        "--roll-deg",
        "30",
        "--out",
        out,
    ];
    args.extend_from_slice(extra);
    ok(&acch(&args, d));
}

/// The figures two reports must share, and their per-image rows.
fn assert_same_figures(a: &serde_json::Value, b: &serde_json::Value) {
    for key in [
        "n",
        "not_found",
        "failure_rate",
        "accepted_rate",
        "acc_failure_rate",
        "rotation_within_10deg",
        "acc_rotation_within_10deg",
    ] {
        assert_eq!(a[key], b[key], "{key}: {} vs {}", a[key], b[key]);
    }
    for key in [
        "mean_phi_err_deg",
        "mean_theta_err_deg",
        "mean_roll_err_deg",
        "outside_theta_range_rate",
    ] {
        let (x, y) = (a[key].as_f64().unwrap(), b[key].as_f64().unwrap());
        assert!((x - y).abs() < 1e-6, "{key}: {x} vs {y}");
    }
    let (ra, rb) = (
        a["images"].as_array().unwrap(),
        b["images"].as_array().unwrap(),
    );
    assert_eq!(ra.len(), rb.len());
    for (x, y) in ra.iter().zip(rb) {
        assert_eq!(
            x["estimate_deg"], y["estimate_deg"],
            "{} vs {}",
            x["name"], y["name"]
        );
        assert_eq!(x["accepted"], y["accepted"]);
        for k in 0..3 {
            let (p, q) = (
                x["truth_deg"][k].as_f64().unwrap(),
                y["truth_deg"][k].as_f64().unwrap(),
            );
            let d = (p - q).rem_euclid(360.0);
            assert!(
                d.min(360.0 - d) < 1e-6,
                "{}: truth {k} {p} vs {q}",
                x["name"]
            );
        }
        let (p, q) = (
            x["distance_m"].as_f64().unwrap(),
            y["distance_m"].as_f64().unwrap(),
        );
        assert!((p - q).abs() < 1e-9, "distance {p} vs {q}");
    }
}

#[test]
fn a_bop_dataset_written_and_read_back_gives_the_figures_of_the_same_views() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(&acch(
        &[
            "train",
            "--object",
            "can",
            "--confidence-scenes",
            "40",
            "--out",
            "can.acchdb",
        ],
        d,
    ));
    render(d, "labels", &[]);
    render(d, "bop", &["--format", "bop", "--bop-object-id", "3"]);

    // An independent reader of the spec accepts the files.
    let check = Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bop_check.py"))
        .args([d.join("bop").to_str().unwrap(), "test", "3"])
        .output()
        .expect("python3 with numpy and pillow (scripts/test installs them)");
    assert!(
        check.status.success(),
        "bop_check.py: {}{}",
        String::from_utf8_lossy(&check.stdout),
        String::from_utf8_lossy(&check.stderr)
    );
    let checked: serde_json::Value = serde_json::from_slice(&check.stdout).unwrap();
    assert_eq!(checked["instances"], 24, "{checked}");

    for segment in ["mask", "auto"] {
        let (a, b) = (
            format!("labels-{segment}.json"),
            format!("bop-{segment}.json"),
        );
        ok(&acch(
            &[
                "eval",
                "--labels",
                "labels",
                "--db",
                "can.acchdb",
                "--segment",
                segment,
                "--roll-search-deg",
                "45",
                "--json",
                &a,
            ],
            d,
        ));
        ok(&acch(
            &[
                "eval",
                "--bop",
                "bop",
                "--object",
                "3",
                "--db",
                "can.acchdb",
                "--segment",
                segment,
                "--roll-search-deg",
                "45",
                "--json",
                &b,
            ],
            d,
        ));
        let (a, b) = (json(&d.join(a)), json(&d.join(b)));
        assert_eq!(a["n"], 24);
        assert_same_figures(&a, &b);
        // The views are rolled up to 30°, beyond the database's upright
        // views: the rolls read back from the BOP poses are the rendered
        // ones, not zero.
        let rolls: Vec<f64> = b["images"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["truth_deg"][2].as_f64().unwrap().abs())
            .collect();
        assert!(rolls.iter().any(|&r| r > 10.0), "{rolls:?}");
        // A working estimator on its own renders, searching the roll: most
        // rotations are right.
        assert!(a["rotation_within_10deg"].as_f64().unwrap() > 0.7, "{a}");
    }
}

#[test]
fn bad_bop_datasets_are_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = acch(
        &[
            "render", "--object", "tricolor", "--views", "random:2", "--format", "bop", "--out",
            "bop",
        ],
        d,
    );
    ok(&out);
    let db = ["--db", "nonexistent.acchdb"];
    // An object id the dataset does not have.
    let e = failed(&acch(
        &[&["eval", "--bop", "bop", "--object", "9"][..], &db[..]].concat(),
        d,
    ));
    assert!(e.contains("models_info.json") && e.contains("9"), "{e}");
    // A name where BOP wants a number.
    let e = failed(&acch(&["eval", "--bop", "bop", "--object", "can"], d));
    assert!(e.contains("obj_id"), "{e}");
    // A missing image.
    std::fs::remove_file(d.join("bop/test/000000/rgb/000001.png")).unwrap();
    let e = failed(&acch(
        &[&["eval", "--bop", "bop", "--object", "1"][..], &db[..]].concat(),
        d,
    ));
    assert!(
        e.contains("000001.png") && e.contains("missing image"),
        "{e}"
    );
    // A malformed annotation file.
    std::fs::write(d.join("bop/test/000000/scene_gt.json"), "{\"0\": [").unwrap();
    let e = failed(&acch(
        &[&["eval", "--bop", "bop", "--object", "1"][..], &db[..]].concat(),
        d,
    ));
    assert!(
        e.contains("scene_gt.json") && e.contains("not a valid BOP file"),
        "{e}"
    );
}
