//! The peer a user would pick instead, LINE-2D (OpenCV contrib's
//! `cv2.linemod`, measured by `eval/line2d.py`), on the very images acch
//! estimates: set up fairly it is right on the untextured tricolor, it
//! flips φ by 180° on the printed box, whose outline is the same from
//! behind, and acch on the same box views is right and accepts them. Each
//! check can fail: a broken peer (a wrong rotation convention, wrong
//! templates) fails the first, a broken acch the last.

mod common;

use common::{acch, ok};
use serde_json::Value;
use std::path::Path;
use std::process::Command;

/// Renders `object`'s training grid and 20 held-out test views on
/// background A into `dir`; returns (training folder, test folder).
fn render(dir: &Path, object: &str) -> (String, String) {
    let (train, test) = (
        dir.join(format!("train-{object}")),
        dir.join(format!("test-{object}")),
    );
    ok(&acch(
        &[
            "render",
            "--object",
            object,
            "--out",
            train.to_str().unwrap(),
        ],
        dir,
    ));
    ok(&acch(
        &[
            "render",
            "--object",
            object,
            "--views",
            "random:20",
            "--background",
            "A",
            "--textures",
            "held-out",
            "--seed",
            "13",
            "--out",
            test.to_str().unwrap(),
        ],
        dir,
    ));
    (train.display().to_string(), test.display().to_string())
}

/// LINE-2D's metrics on the test folder, templates from the training one.
fn line2d(dir: &Path, (train, test): &(String, String), name: &str) -> Value {
    let json = dir.join(format!("{name}.json"));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("eval/line2d.py");
    let out = Command::new("python3")
        .arg(script)
        .args(["--train", train, "--test", test, "--json"])
        .arg(&json)
        .output()
        .expect("python3 with opencv-contrib-python-headless (scripts/test installs it)");
    ok(&out);
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    report["tests"][0]["metrics"].clone()
}

#[test]
fn line2d_is_fair_on_plain_blocks_flips_the_box_and_acch_does_not() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let f = |v: &Value, k: &str| v[k].as_f64().unwrap_or_else(|| panic!("no {k} in {v}"));

    let tricolor = line2d(d, &render(d, "tricolor"), "tricolor");
    eprintln!(
        "LINE-2D tricolor: failures {:.2}, flips {:.2}",
        f(&tricolor, "failure_rate"),
        f(&tricolor, "flip_rate")
    );
    assert!(
        f(&tricolor, "failure_rate") <= 0.1,
        "the peer is broken: {tricolor}"
    );

    let box_views = render(d, "fruitbox");
    let fruitbox = line2d(d, &box_views, "fruitbox");
    eprintln!(
        "LINE-2D fruitbox: failures {:.2}, flips {:.2}, failures among its 70 % most similar {:.2}",
        f(&fruitbox, "failure_rate"),
        f(&fruitbox, "flip_rate"),
        f(&fruitbox, "keep70_failure_rate")
    );
    assert!(f(&fruitbox, "flip_rate") >= 0.1, "{fruitbox}");
    assert!(f(&fruitbox, "failure_rate") >= 0.2, "{fruitbox}");

    let json = d.join("acch.json");
    ok(&acch(
        &[
            "eval",
            "--labels",
            &box_views.1,
            "--segment",
            "auto",
            "--object",
            "fruitbox",
            "--json",
            json.to_str().unwrap(),
        ],
        d,
    ));
    let ours: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    eprintln!(
        "acch fruitbox: failures {:.2}, accepted {:.2}, failures among accepted {:.2}",
        f(&ours, "failure_rate"),
        f(&ours, "accepted_rate"),
        f(&ours, "acc_failure_rate")
    );
    assert!(f(&ours, "failure_rate") <= 0.05, "{ours}");
    assert!(f(&ours, "accepted_rate") >= 0.9, "{ours}");
    assert!(f(&ours, "acc_failure_rate") == 0.0, "{ours}");
}
