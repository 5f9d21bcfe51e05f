//! View sets, the labels file format and the streaming trajectory.

use acch_capture::labels::{HEADER, LabelRow, read_labels, write_labels};
use acch_capture::{BBox, CaptureError, Trajectory, ViewSpec, derive_seed};

#[test]
fn training_grid_has_216_views_theta_slice_by_slice() {
    let spec: ViewSpec = "grid:45,50,60,70,80,90:10".parse().unwrap();
    assert_eq!(spec, ViewSpec::training_grid());
    assert_eq!(spec.to_string(), "grid:45,50,60,70,80,90:10");
    assert_eq!(spec.len(), 216);
    let views = spec.views(5.0, 0);
    assert_eq!(views.len(), 216);
    for (i, v) in views.iter().enumerate() {
        assert_eq!(v.theta_deg, [45.0, 50.0, 60.0, 70.0, 80.0, 90.0][i / 36]);
        assert_eq!(v.phi_deg, 10.0 * (i % 36) as f64);
        assert_eq!(v.distance, 5.0);
    }
    let small: ViewSpec = "grid:60,90:90".parse().unwrap();
    let phis: Vec<f64> = small.views(5.0, 0).iter().map(|v| v.phi_deg).collect();
    assert_eq!(phis, [0.0, 90.0, 180.0, 270.0, 0.0, 90.0, 180.0, 270.0]);
    // A step that does not divide 360 stops below 360.
    let odd: ViewSpec = "grid:45:70".parse().unwrap();
    let phis: Vec<f64> = odd.views(5.0, 0).iter().map(|v| v.phi_deg).collect();
    assert_eq!(phis, [0.0, 70.0, 140.0, 210.0, 280.0, 350.0]);
    assert_eq!(odd.len(), 6);
}

#[test]
fn random_views_are_seeded_and_in_range() {
    let spec: ViewSpec = "random:500".parse().unwrap();
    assert_eq!(spec.to_string(), "random:500");
    let a = spec.views(4.0, 9);
    assert_eq!(a.len(), 500);
    assert_eq!(a, spec.views(4.0, 9));
    assert_ne!(a, spec.views(4.0, 10));
    assert!(
        a.iter()
            .all(|v| (45.0..=90.0).contains(&v.theta_deg) && (0.0..360.0).contains(&v.phi_deg))
    );
    // Roughly uniform: both halves of each range are used.
    assert!(a.iter().filter(|v| v.theta_deg > 67.5).count() > 200);
    assert!(a.iter().filter(|v| v.phi_deg > 180.0).count() > 200);
}

#[test]
fn bad_view_specs_are_clear_errors() {
    for (spec, needle) in [
        ("grid:45,95:10", "95"),
        ("grid:45,x:10", "'x'"),
        ("grid:45:0", "step"),
        ("random:0", "at least 1"),
        ("random:-3", "'-3'"),
        ("spiral:3", "unrecognised"),
    ] {
        let err = spec.parse::<ViewSpec>().unwrap_err();
        assert!(matches!(err, CaptureError::InvalidViewSpec { .. }));
        let msg = err.to_string();
        assert!(msg.contains(spec) && msg.contains(needle), "{spec}: {msg}");
    }
}

#[test]
fn labels_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("labels.csv");
    let rows = vec![
        LabelRow {
            file: "view_0000.png".into(),
            theta_deg: 45.0,
            phi_deg: 0.0,
            distance_m: 1.25,
            bbox: Some(BBox {
                x: 270,
                y: 180,
                width: 101,
                height: 121,
            }),
            mask: Some("view_0000_mask.png".into()),
            roll_deg: 0.0,
        },
        LabelRow {
            file: "real, odd \"name\".png".into(),
            theta_deg: 67.123_456_789_012_34 + 1e-13,
            phi_deg: 359.99999999999994,
            distance_m: 0.1 + 0.2,
            bbox: None,
            mask: None,
            roll_deg: -123.456_789_012_345_6,
        },
        LabelRow {
            file: "c.png".into(),
            theta_deg: 90.0,
            phi_deg: 10.0,
            distance_m: 1.0,
            bbox: None,
            mask: None,
            roll_deg: 180.0,
        },
    ];
    write_labels(&path, &rows).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with(&format!("{HEADER}\n")));
    assert!(
        text.contains("view_0000.png,45,0,1.25,270,180,101,121,view_0000_mask.png,0\n"),
        "{text}"
    );
    assert_eq!(read_labels(&path).unwrap(), rows);
}

#[test]
fn hand_written_labels_with_fewer_columns_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("real.csv");
    std::fs::write(
        &path,
        "phi_deg,theta_deg,file,distance_m\n-10,60,img1.png,0.8\n\n370,90,img2.png,0.8\n",
    )
    .unwrap();
    let rows = read_labels(&path).unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(
        (rows[0].file.as_str(), rows[0].theta_deg, rows[0].phi_deg),
        ("img1.png", 60.0, 350.0)
    );
    assert_eq!(rows[1].phi_deg, 10.0);
    assert_eq!(rows[1].bbox, None);
    assert_eq!(rows[1].roll_deg, 0.0);
}

#[test]
fn labels_without_roll_read_as_unrolled_and_roll_is_checked() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.csv");
    // A file written before the roll_deg column existed.
    std::fs::write(
        &path,
        "file,theta_deg,phi_deg,distance_m,bbox_x,bbox_y,bbox_w,bbox_h,mask\n\
         view_0000.png,45,0,1.03,270,180,101,121,view_0000_mask.png\n",
    )
    .unwrap();
    let rows = read_labels(&path).unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].roll_deg, 0.0);
    assert_eq!(rows[0].mask.as_deref(), Some("view_0000_mask.png"));
    // An empty roll is 0; rolls are wrapped into (-180, 180].
    std::fs::write(
        &path,
        "roll_deg,file,theta_deg,phi_deg,distance_m\n,a.png,45,0,1\n-180,b.png,45,0,1\n190,c.png,45,0,1\n",
    )
    .unwrap();
    let rolls: Vec<f64> = read_labels(&path)
        .unwrap()
        .iter()
        .map(|r| r.roll_deg)
        .collect();
    assert_eq!(rolls, [0.0, 180.0, -170.0]);
    for (bad, needle) in [("x", "'x' is not a number"), ("inf", "not finite")] {
        std::fs::write(
            &path,
            format!("file,theta_deg,phi_deg,distance_m,roll_deg\na.png,45,0,1,{bad}\n"),
        )
        .unwrap();
        let msg = read_labels(&path).unwrap_err().to_string();
        assert!(
            msg.contains("old.csv:2:") && msg.contains("roll_deg") && msg.contains(needle),
            "{msg}"
        );
    }
}

#[test]
fn bad_labels_name_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.csv");
    let cases = [
        ("file,theta_deg,phi_deg\na.png,45,0\n", 1, "distance_m"),
        (
            "file,theta_deg,phi_deg,distance\na.png,45,0,5\n",
            1,
            "now 'distance_m', in metres",
        ),
        (
            &format!("{HEADER}\na.png,45,0,5,,,,,,\nb.png,95,0,5,,,,,,\n"),
            3,
            "95",
        ),
        (&format!("{HEADER}\na.png,4x5,0,5,,,,,,\n"), 2, "'4x5'"),
        (
            &format!("{HEADER}\na.png,45,0,5,1,2,,,,\n"),
            2,
            "all set or all empty",
        ),
        (&format!("{HEADER}\na.png,45,0,5,1,2\n"), 2, "fields"),
        (&format!("{HEADER}\na.png,45,0,-5,,,,,,\n"), 2, "distance_m"),
        (
            &format!("{HEADER}\n\"a.png,45,0,5,,,,,,\n"),
            2,
            "unterminated",
        ),
        ("", 1, "empty"),
    ];
    for (text, line, needle) in cases {
        std::fs::write(&path, text).unwrap();
        let err = read_labels(&path).unwrap_err();
        assert!(
            matches!(err, CaptureError::Labels { line: l, .. } if l == line),
            "{err:?}"
        );
        let msg = err.to_string();
        assert!(
            msg.contains("bad.csv") && msg.contains(&format!(":{line}:")) && msg.contains(needle),
            "{msg}"
        );
    }
    let missing = read_labels(dir.path().join("nope.csv")).unwrap_err();
    assert!(missing.to_string().contains("nope.csv"));
}

#[test]
fn trajectory_is_smooth_bounded_and_consistent() {
    let t = Trajectory::new(3, 30.0, 5.0).unwrap();
    assert_eq!(t, Trajectory::new(3, 30.0, 5.0).unwrap());
    assert_ne!(t, Trajectory::new(4, 30.0, 5.0).unwrap());
    let frames: Vec<_> = t.frames().take(30 * 120).collect();
    assert_eq!(frames[0].camera_motion, glam::DAffine3::IDENTITY);
    let mut phi_travel = 0.0;
    for w in frames.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        assert_eq!(b.index, a.index + 1);
        assert!((b.time_s - b.index as f64 / 30.0).abs() < 1e-12);
        assert!(
            (45.0..=90.0).contains(&b.view.theta_deg),
            "theta {}",
            b.view.theta_deg
        );
        assert!((0.0..360.0).contains(&b.view.phi_deg));
        assert_eq!(b.view.distance, 5.0);
        let dtheta = (b.view.theta_deg - a.view.theta_deg).abs();
        let dphi = ((b.view.phi_deg - a.view.phi_deg + 540.0) % 360.0 - 180.0).abs();
        assert!(
            dtheta < 0.5 && dphi < 1.5,
            "jump at frame {}: {dtheta} {dphi}",
            b.index
        );
        phi_travel += dphi;
        // previous_camera_from_current: composing with the previous pose gives the current one.
        let composed = a.view.world_from_camera() * b.camera_motion;
        assert!(composed.abs_diff_eq(b.view.world_from_camera(), 1e-9));
        assert!(b.camera_motion.translation.length() < 0.2);
    }
    // Over two minutes the camera covers the hemisphere: all azimuths, wide elevation range.
    assert!(phi_travel > 360.0, "phi travel {phi_travel}");
    let thetas: Vec<f64> = frames.iter().map(|f| f.view.theta_deg).collect();
    let (lo, hi) = thetas
        .iter()
        .fold((90.0f64, 45.0f64), |(l, h), &t| (l.min(t), h.max(t)));
    assert!(lo < 60.0 && hi > 75.0, "theta range {lo}..{hi}");
    assert_eq!(t.frame(77), frames[77]);
    assert!(Trajectory::new(0, 0.0, 5.0).is_err());
    assert!(Trajectory::new(0, 30.0, -1.0).is_err());
}

#[test]
fn derived_seeds_differ() {
    let s: std::collections::HashSet<u64> = (0..1000).map(|i| derive_seed(0, i)).collect();
    assert_eq!(s.len(), 1000);
    assert_ne!(derive_seed(1, 0), derive_seed(0, 0));
}
