//! `acch render` end to end: runs the real binary.

use std::path::Path;
use std::process::Command;

fn acch() -> Command {
    Command::new(env!("CARGO_BIN_EXE_acch"))
}

fn read_png_size(path: &Path) -> (u32, u32) {
    image::image_dimensions(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn renders_a_small_grid_with_labels_truth_and_contact_sheet() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fb");
    let sheet = dir.path().join("sheets/sheet.png");
    let status = acch()
        .args([
            "render",
            "--object",
            "fruitbox",
            "--views",
            "grid:60,90:90",
            "--background",
            "A",
        ])
        .args(["--seed", "3", "--noise", "2", "--out"])
        .arg(&out)
        .arg("--contact-sheet")
        .arg(&sheet)
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );

    let labels = std::fs::read_to_string(out.join("labels.csv")).unwrap();
    let lines: Vec<&str> = labels.lines().collect();
    assert_eq!(
        lines[0],
        "file,theta_deg,phi_deg,distance_m,bbox_x,bbox_y,bbox_w,bbox_h,mask,roll_deg"
    );
    assert_eq!(lines.len(), 1 + 8);
    let expected = [
        (60, 0),
        (60, 90),
        (60, 180),
        (60, 270),
        (90, 0),
        (90, 90),
        (90, 180),
        (90, 270),
    ];
    for (i, (line, (theta, phi))) in lines[1..].iter().zip(expected).enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 10, "{line}");
        assert_eq!(f[0], format!("view_{i:04}.png"));
        assert_eq!(f[1].parse::<f64>().unwrap(), theta as f64);
        assert_eq!(f[2].parse::<f64>().unwrap(), phi as f64);
        // 5 bounding radii of the 24 x 15 x 30 cm box, in metres.
        let radius_m = 0.5 * (0.24f64.powi(2) + 0.15f64.powi(2) + 0.30f64.powi(2)).sqrt();
        let distance_m: f64 = f[3].parse().unwrap();
        assert!((distance_m - 5.0 * radius_m).abs() < 1e-6, "{line}");
        let (bx, by, bw, bh): (u32, u32, u32, u32) = (
            f[4].parse().unwrap(),
            f[5].parse().unwrap(),
            f[6].parse().unwrap(),
            f[7].parse().unwrap(),
        );
        assert!(
            bw > 30 && bh > 30 && bx + bw <= 640 && by + bh <= 480,
            "{line}"
        );
        assert_eq!(f[8], format!("view_{i:04}_mask.png"));
        assert_eq!(read_png_size(&out.join(f[0])), (640, 480));
        let mask = image::open(out.join(f[8])).unwrap().to_luma8();
        assert_eq!(mask.dimensions(), (640, 480));
        assert!(mask.pixels().all(|p| p[0] == 0 || p[0] == 255));
        assert_eq!(
            mask.get_pixel(320, 240)[0],
            255,
            "object at the centre of {}",
            f[0]
        );
    }
    // The library reads what the command wrote.
    let rows = acch_capture::labels::read_labels(out.join("labels.csv")).unwrap();
    assert_eq!(rows.len(), 8);

    let truth = std::fs::read_to_string(out.join("truth.jsonl")).unwrap();
    let truth: Vec<serde_json::Value> = truth
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(truth.len(), 8);
    let t = &truth[4];
    assert_eq!(t["file"], "view_0004.png");
    assert_eq!(t["theta_deg"], 90.0);
    assert_eq!(t["intrinsics"]["fx"], 500.0);
    assert_eq!(t["intrinsics"]["cx"], 319.5);
    let m = &t["world_from_camera"];
    // Top view from above: camera at (0, 0, 5) looking down (forward = -z).
    assert!((m[2][3].as_f64().unwrap() - 5.0).abs() < 1e-9);
    assert!((m[2][2].as_f64().unwrap() + 1.0).abs() < 1e-9);
    assert_eq!(m[3], serde_json::json!([0.0, 0.0, 0.0, 1.0]));
    assert_eq!(
        t["bbox"]["width"].as_u64().unwrap(),
        rows[4].bbox.unwrap().width as u64
    );

    let (w, h) = read_png_size(&sheet);
    assert!(w > 128 * 8 && h > 96 && h < 200, "contact sheet {w}x{h}");

    // Same command line, same bytes.
    let again = dir.path().join("again");
    let status = acch()
        .args([
            "render",
            "--object",
            "fruitbox",
            "--views",
            "grid:60,90:90",
            "--background",
            "A",
        ])
        .args(["--seed", "3", "--noise", "2", "--out"])
        .arg(&again)
        .status()
        .unwrap();
    assert!(status.success());
    for i in 0..8 {
        let f = format!("view_{i:04}.png");
        assert_eq!(
            std::fs::read(out.join(&f)).unwrap(),
            std::fs::read(again.join(&f)).unwrap(),
            "{f}"
        );
    }
}

#[test]
fn renders_an_obj_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("duck");
    let o = acch()
        .args([
            "render",
            "--mesh",
            "/work/shared/data/duck/duck.obj",
            "--views",
            "random:3",
            "--background",
            "clutter",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows = acch_capture::labels::read_labels(out.join("labels.csv")).unwrap();
    assert_eq!(rows.len(), 3);
    assert!(
        rows.iter()
            .all(|r| r.bbox.is_some() && (45.0..=90.0).contains(&r.theta_deg))
    );
}

#[test]
fn bad_background_fails_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let o = acch()
        .args([
            "render",
            "--object",
            "fruitbox",
            "--background",
            "marble",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("marble") && err.contains("clutter-similar"),
        "{err}"
    );
}

#[test]
fn bad_inputs_fail_with_clear_messages() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&[&str], &str); 6] = [
        (&["--object", "banana"], "banana"),
        (&["--mesh", "/no/such/mesh.obj"], "/no/such/mesh.obj"),
        (&["--object", "can", "--views", "grid:45,100:10"], "100"),
        (
            &["--object", "can", "--distance", "-1"],
            "distance -1 must be",
        ),
        (&["--object", "can", "--noise", "-3"], "--noise -3 must be"),
        (&[], "--object"),
    ];
    for (args, needle) in cases {
        let o = acch()
            .arg("render")
            .args(args)
            .arg("--out")
            .arg(dir.path())
            .output()
            .unwrap();
        assert!(!o.status.success(), "{args:?} should fail");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
}

#[test]
fn help_explains_every_option() {
    let o = acch().args(["render", "--help"]).output().unwrap();
    assert!(o.status.success());
    let help = String::from_utf8_lossy(&o.stdout);
    for opt in [
        "--object",
        "--mesh",
        "--mesh-up",
        "--views",
        "--background",
        "--seed",
        "--out",
        "--contact-sheet",
        "--distance",
        "--noise",
        "--blur",
        "--brightness",
    ] {
        assert!(help.contains(opt), "--help lacks {opt}:\n{help}");
    }
    assert!(help.contains("grid:") && help.contains("random:") && help.contains("clutter-similar"));
}
