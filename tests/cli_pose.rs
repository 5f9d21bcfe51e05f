//! End-to-end tests of the `acch` binary: train a database, render test
//! images, estimate their pose, export features for NumPy, and fail clearly
//! on bad input.

mod common;

use common::{acch, ok};
use std::process::Command;

/// The value after `key` in "key value" output.
fn field(text: &str, key: &str) -> f32 {
    let mut words = text.split_whitespace();
    while let Some(w) = words.next() {
        if w == key {
            return words.next().unwrap().parse().unwrap();
        }
    }
    panic!("no '{key}' in {text}");
}

fn phi_error(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

#[test]
fn train_estimate_and_features_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(&acch(
        &["train", "--object", "fruitbox", "--out", "fb.acchdb"],
        d,
    ));
    ok(&acch(
        &[
            "render", "--object", "fruitbox", "--views", "random:3", "--seed", "11", "--out",
            "test",
        ],
        d,
    ));
    let labels = std::fs::read_to_string(d.join("test/labels.csv")).unwrap();
    for (i, line) in labels.lines().skip(1).enumerate() {
        let cols: Vec<&str> = line.split(',').collect();
        let (theta, phi): (f32, f32) = (cols[1].parse().unwrap(), cols[2].parse().unwrap());
        // The labels' distance, metres: the known distance of the estimate.
        let distance_m = cols[3];
        let image = format!("test/view_{i:04}.png");
        let mask = format!("test/view_{i:04}_mask.png");
        let out = ok(&acch(
            &[
                "estimate",
                "--db",
                "fb.acchdb",
                &image,
                "--mask",
                &mask,
                "--distance-m",
                distance_m,
                "--csv",
                "response.csv",
                "--plot",
                "response.png",
            ],
            d,
        ));
        let (est_theta, est_phi) = (field(&out, "theta"), field(&out, "phi"));
        assert!(
            (est_theta - theta).abs() <= 10.0,
            "theta {est_theta} vs {theta}\n{out}"
        );
        assert!(
            phi_error(est_phi, phi) <= 20.0,
            "phi {est_phi} vs {phi}\n{out}"
        );
        assert!(out.contains("top 5 views"), "{out}");
        // The default database carries a confidence network.
        assert!(
            out.contains("confidence") && (out.contains("accepted") || out.contains("rejected")),
            "{out}"
        );
    }
    let csv = std::fs::read_to_string(d.join("response.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 216, "one row per training view");
    let png = image::open(d.join("response.png")).unwrap();
    assert!(png.width() > 500);

    ok(&acch(
        &[
            "features",
            "--db",
            "fb.acchdb",
            "test/view_0000.png",
            "--mask",
            "test/view_0000_mask.png",
            "--out",
            "h.npy",
        ],
        d,
    ));
    // NumPy reads the array independently of our code.
    let py = Command::new("python3")
        .args([
            "-c",
            "import numpy as np, sys; a = np.load(sys.argv[1]); \
             print(a.dtype, a.shape, round(float(a.sum()), 4), bool((a >= 0).all()))",
            d.join("h.npy").to_str().unwrap(),
        ])
        .output()
        .expect("python3 (install numpy: pip install numpy)");
    let text = String::from_utf8_lossy(&py.stdout);
    assert!(
        py.status.success(),
        "{}",
        String::from_utf8_lossy(&py.stderr)
    );
    assert_eq!(text.trim(), "float32 (12, 40, 40) 1.0 True");
}

#[test]
fn bad_input_gives_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("junk.acchdb"), b"ACCHDB\r\n\x01\x00\x00\x00garbage").unwrap();
    std::fs::write(d.join("img.png"), b"not a png").unwrap();

    let out = acch(
        &[
            "estimate",
            "--db",
            "junk.acchdb",
            "img.png",
            "--mask",
            "img.png",
        ],
        d,
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("junk.acchdb") && err.contains("truncated"),
        "{err}"
    );

    let out = acch(&["estimate", "--db", "missing.acchdb", "img.png"], d);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("missing.acchdb"), "{err}");

    let out = acch(
        &[
            "train",
            "--object",
            "fruitbox",
            "--views",
            "grid:60:90",
            "--out",
            "small.acchdb",
        ],
        d,
    );
    ok(&out);
    let out = acch(
        &[
            "estimate",
            "--db",
            "small.acchdb",
            "img.png",
            "--mask",
            "img.png",
        ],
        d,
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("img.png"), "{err}");
    assert!(!err.contains("panicked"), "{err}");

    let out = acch(
        &[
            "train", "--object", "fruitbox", "--r-max", "5", "--out", "x.acchdb",
        ],
        d,
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("r_max"));
    assert!(!d.join("x.acchdb").exists(), "nothing written on error");
}

/// Training from a folder of labelled images (the format `acch render`
/// writes, as real images would be labelled) and estimating one of them.
#[test]
fn trains_from_a_folder_of_labelled_images() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The can's photographs in `folder` (rolled as `roll` says), trained.
    let photographed = |folder: &str, roll: &str| {
        ok(&acch(
            &[
                "render",
                "--object",
                "can",
                "--views",
                "grid:60,90:30",
                "--roll-deg",
                roll,
                "--out",
                folder,
            ],
            d,
        ));
        let db = format!("{folder}.acchdb");
        ok(&acch(&["train", "--images", folder, "--out", &db], d))
    };
    let out = photographed("imgs", "0");
    assert!(out.contains("trained 24 views"), "{out}");
    // Upright photographs: no roll searched at runs.
    assert!(out.contains("no roll search recorded"), "{out}");
    let labels = std::fs::read_to_string(d.join("imgs/labels.csv")).unwrap();
    let row: Vec<&str> = labels.lines().nth(6).unwrap().split(',').collect();
    let (theta, phi): (f32, f32) = (row[1].parse().unwrap(), row[2].parse().unwrap());
    let out = ok(&acch(
        &[
            "estimate",
            "--db",
            "imgs.acchdb",
            "imgs/view_0005.png",
            "--mask",
            "imgs/view_0005_mask.png",
            "--wta",
        ],
        d,
    ));
    // A training view is its own best match.
    assert_eq!(
        (field(&out, "theta"), field(&out, "phi")),
        (theta, phi),
        "{out}"
    );

    // Photographs from a camera that rolled: the runs search as far as 95 %
    // of them roll, rounded up to 15°.
    let out = photographed("rolled", "40");
    let labels = std::fs::read_to_string(d.join("rolled/labels.csv")).unwrap();
    let mut rolls: Vec<f64> = labels
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(9).unwrap().parse::<f64>().unwrap().abs())
        .collect();
    rolls.sort_by(f64::total_cmp);
    let covered = (rolls[rolls.len() * 95 / 100] / 15.0).ceil() * 15.0;
    assert!(covered >= 15.0, "{rolls:?}");
    assert!(
        out.contains(&format!("roll search ±{covered}° recorded")),
        "{covered} {out}"
    );

    let out = acch(
        &[
            "train",
            "--object",
            "can",
            "--confidence-threshold",
            "1.5",
            "--out",
            "x.acchdb",
        ],
        d,
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--confidence-threshold"));
}
