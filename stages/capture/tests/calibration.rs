//! Calibration files (ROS camera_info and OpenCV FileStorage YAML) and lens
//! distortion, checked against arithmetic done by hand.

use std::path::{Path, PathBuf};

use acch_capture::{Calibration, CaptureError, Distortion, DistortionModel, Intrinsics};
use glam::DVec2;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/calibration")
        .join(name)
}

fn read(name: &str) -> String {
    std::fs::read_to_string(data(name)).unwrap()
}

/// Writes `text` to `dir/name` and loads it, expecting an error that names the file.
fn load_err(dir: &Path, name: &str, text: &[u8]) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    let err = Calibration::load(&path).expect_err("the file must be refused");
    assert!(
        matches!(&err, CaptureError::Calibration { path: p, .. } if p == &path),
        "{err:?}"
    );
    let msg = err.to_string();
    assert!(msg.contains(name), "the error must name the file: {msg}");
    msg
}

const K: (f64, f64, f64, f64) = (525.3, 526.1, 318.9, 241.2);
const PLUMB: [f64; 5] = [-0.28, 0.09, 0.0012, -0.0007, -0.011];

#[test]
fn ros_and_opencv_files_load_identically() {
    let ros = Calibration::load(&data("ros_plumb_bob.yaml")).unwrap();
    let cv = Calibration::load(&data("opencv_plumb_bob.yaml")).unwrap();
    let expected = Intrinsics {
        width: 640,
        height: 480,
        fx: K.0,
        fy: K.1,
        cx: K.2,
        cy: K.3,
    };
    assert_eq!(ros.intrinsics, expected);
    assert_eq!(cv.intrinsics, expected);
    assert_eq!(ros.distortion, Distortion::plumb_bob(PLUMB));
    assert_eq!(cv.distortion, ros.distortion);
    assert_eq!(cv.distortion.model, DistortionModel::PlumbBob);
    assert_eq!(ros, cv);
}

#[test]
fn rational_polynomial_ros_file_has_eight_coefficients() {
    let c = Calibration::load(&data("ros_rational_polynomial.yaml")).unwrap();
    assert_eq!(c.distortion.model, DistortionModel::RationalPolynomial);
    assert_eq!(
        c.distortion.coefficients,
        [0.61, 0.05, 0.0009, -0.0004, 0.001, 0.69, 0.11, 0.004]
    );
    assert_eq!((c.intrinsics.width, c.intrinsics.height), (1280, 720));
    assert_eq!((c.intrinsics.fx, c.intrinsics.cy), (612.4, 362.3));
}

#[test]
fn hand_computed_plumb_bob_point() {
    let calib = Calibration::load(&data("ros_plumb_bob.yaml")).unwrap();
    let distorted = DVec2::new(600.0, 60.0);
    let ideal = calib.undistort_pixel(distorted);

    // Known value, solved independently (Newton with a numerical Jacobian,
    // in Python): barrel distortion pulled this pixel towards the centre by
    // (41.139, -26.759) px.
    assert!((ideal.x - 641.139_391_004_807_5).abs() < 1e-6, "{ideal:?}");
    assert!((ideal.y - 33.240_572_471_392_65).abs() < 1e-6, "{ideal:?}");
    let moved = ideal - distorted;
    assert!((moved.x - 41.139_391).abs() < 1e-6 && (moved.y + 26.759_428).abs() < 1e-6);

    // By hand: distorting the ideal point gives the pixel back.
    let (fx, fy, cx, cy) = K;
    let [k1, k2, p1, p2, k3] = PLUMB;
    let x = (ideal.x - cx) / fx; // 0.613438779754
    let y = (ideal.y - cy) / fy; // -0.395284979146
    let r2 = x * x + y * y; // 0.532557351244
    let radial = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2; // 0.874748034116
    let tx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x); // -0.001481579662
    let ty = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y; // 0.001353545726
    assert!((r2 - 0.532_557_351_244).abs() < 1e-9, "{r2}");
    assert!((radial - 0.874_748_034_116).abs() < 1e-9, "{radial}");
    assert!((tx + 0.001_481_579_662).abs() < 1e-11 && (ty - 0.001_353_545_726).abs() < 1e-11);
    let u = fx * (x * radial + tx) + cx;
    let v = fy * (y * radial + ty) + cy;
    assert!(
        (u - 600.0).abs() < 1e-9 && (v - 60.0).abs() < 1e-9,
        "({u}, {v})"
    );
}

#[test]
fn hand_distorted_ideal_points_undistort_back() {
    // Plumb bob: ideal pixel (100, 420) distorted by hand.
    let (fx, fy, cx, cy) = K;
    let [k1, k2, p1, p2, k3] = PLUMB;
    let ideal = DVec2::new(100.0, 420.0);
    let (x, y) = ((ideal.x - cx) / fx, (ideal.y - cy) / fy);
    let r2 = x * x + y * y; // 0.289155145822
    let radial = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2; // 0.926295580921
    let raw = DVec2::new(
        fx * (x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)) + cx,
        fy * (y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y) + cy,
    );
    assert!((raw - DVec2::new(115.721_317_341_895, 407.254_351_649_570)).length() < 1e-9);
    let calib = Calibration::load(&data("ros_plumb_bob.yaml")).unwrap();
    let back = calib.undistort_pixel(raw);
    assert!((back - ideal).length() < 1e-6, "{back:?}");

    // Rational polynomial: ideal pixel (1200, 80) of the 1280x720 camera.
    let calib = Calibration::load(&data("ros_rational_polynomial.yaml")).unwrap();
    let k = calib.intrinsics;
    let [k1, k2, p1, p2, k3, k4, k5, k6] = calib.distortion.coefficients;
    let ideal = DVec2::new(1200.0, 80.0);
    let (x, y) = ((ideal.x - k.cx) / k.fx, (ideal.y - k.cy) / k.fy);
    let r2 = x * x + y * y;
    let radial = (1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2)
        / (1.0 + k4 * r2 + k5 * r2 * r2 + k6 * r2 * r2 * r2);
    let raw = DVec2::new(
        k.fx * (x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)) + k.cx,
        k.fy * (y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y) + k.cy,
    );
    assert!(
        (raw - ideal).length() > 10.0,
        "the test point must be visibly distorted"
    );
    let back = calib.undistort_pixel(raw);
    assert!((back - ideal).length() < 1e-6, "{back:?}");
}

/// Undistort then distort every 8th pixel and the image border.
fn round_trip_over_image(calib: &Calibration) {
    let k = &calib.intrinsics;
    let d = &calib.distortion;
    let mut xs: Vec<f64> = (0..k.width).step_by(8).map(f64::from).collect();
    xs.extend([-0.5, f64::from(k.width) - 1.0, f64::from(k.width) - 0.5]);
    let mut ys: Vec<f64> = (0..k.height).step_by(8).map(f64::from).collect();
    ys.extend([-0.5, f64::from(k.height) - 1.0, f64::from(k.height) - 0.5]);
    let mut worst: f64 = 0.0;
    let mut moved: f64 = 0.0;
    for &y in &ys {
        for &x in &xs {
            let pixel = DVec2::new(x, y);
            let ideal = d.undistort_pixel(k, pixel);
            let back = d.distort_pixel(k, ideal);
            worst = worst.max((back - pixel).length());
            moved = moved.max((ideal - pixel).length());
        }
    }
    assert!(
        worst < 1e-6,
        "{:?}: worst round trip error {worst} px",
        d.model
    );
    assert!(
        moved > 20.0,
        "{:?}: the lens must distort visibly, max {moved} px",
        d.model
    );
}

#[test]
fn round_trip_over_the_whole_image_plumb_bob() {
    round_trip_over_image(&Calibration::load(&data("ros_plumb_bob.yaml")).unwrap());
}

#[test]
fn round_trip_over_the_whole_image_rational_polynomial() {
    round_trip_over_image(&Calibration::load(&data("ros_rational_polynomial.yaml")).unwrap());
}

#[test]
fn missing_camera_matrix_names_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let text = read("ros_plumb_bob.yaml").replace(
        "camera_matrix:\n  rows: 3\n  cols: 3\n  data: [525.3, 0, 318.9, 0, 526.1, 241.2, 0, 0, 1]\n",
        "",
    );
    assert!(!text.contains("camera_matrix"));
    let msg = load_err(dir.path(), "no_k.yaml", text.as_bytes());
    assert!(msg.contains("missing key 'camera_matrix'"), "{msg}");

    let text = read("opencv_plumb_bob.yaml").replace("camera_matrix:", "intrinsics:");
    let msg = load_err(dir.path(), "no_k_cv.yaml", text.as_bytes());
    assert!(
        msg.contains("missing key 'camera_matrix'") && msg.contains("cameraMatrix"),
        "{msg}"
    );

    let text = read("ros_plumb_bob.yaml").replace("image_height: 480\n", "");
    let msg = load_err(dir.path(), "no_height.yaml", text.as_bytes());
    assert!(msg.contains("missing key 'image_height'"), "{msg}");
}

#[test]
fn a_3x2_camera_matrix_names_its_shape() {
    let dir = tempfile::tempdir().unwrap();
    let text = read("ros_plumb_bob.yaml").replace(
        "  cols: 3\n  data: [525.3, 0, 318.9, 0, 526.1, 241.2, 0, 0, 1]",
        "  cols: 2\n  data: [525.3, 0, 0, 526.1, 318.9, 241.2]",
    );
    let msg = load_err(dir.path(), "k_3x2.yaml", text.as_bytes());
    assert!(
        msg.contains("camera_matrix") && msg.contains("3x2") && msg.contains("6 data values"),
        "{msg}"
    );

    // rows x cols that disagree with the number of values.
    let text =
        read("ros_plumb_bob.yaml").replace("0, 526.1, 241.2, 0, 0, 1]", "0, 526.1, 241.2, 0, 0]");
    let msg = load_err(dir.path(), "k_8.yaml", text.as_bytes());
    assert!(
        msg.contains("camera_matrix is declared 3x3") && msg.contains("8 data values"),
        "{msg}"
    );
}

#[test]
fn fourteen_coefficients_name_the_count() {
    let dir = tempfile::tempdir().unwrap();
    let fourteen = "[ -2.8e-01, 9.0e-02, 1.2e-03, -7.0e-04, -1.1e-02, 0., 0., 0.,\n       0., 0., 0., 0., 0., 0. ]";
    let text = read("opencv_plumb_bob.yaml")
        .replace("rows: 5", "rows: 14")
        .replace(
            "[ -2.8000000000000003e-01, 8.9999999999999997e-02,\n       1.1999999999999999e-03, -6.9999999999999999e-04,\n       -1.0999999999999999e-02 ]",
            fourteen,
        );
    assert!(text.contains("rows: 14") && text.contains(fourteen));
    let msg = load_err(dir.path(), "d14.yaml", text.as_bytes());
    assert!(
        msg.contains("14 distortion coefficients are not supported"),
        "{msg}"
    );

    let text = read("ros_plumb_bob.yaml").replace(
        "cols: 5\n  data: [-0.28, 0.09, 0.0012, -0.0007, -0.011]",
        "cols: 14\n  data: [-0.28, 0.09, 0.0012, -0.0007, -0.011, 0, 0, 0, 0, 0, 0, 0, 0, 0]",
    );
    let msg = load_err(dir.path(), "d14_ros.yaml", text.as_bytes());
    assert!(
        msg.contains("plumb_bob") && msg.contains("14 are given"),
        "{msg}"
    );
}

#[test]
fn size_mismatch_names_both_sizes() {
    let c = Calibration::load(&data("ros_rational_polynomial.yaml")).unwrap();
    let msg = c.check_size(640, 480).unwrap_err();
    assert!(msg.contains("1280x720") && msg.contains("640x480"), "{msg}");
    assert!(c.check_size(1280, 720).is_ok());
    assert!(c.check_size(720, 1280).is_err());
}

#[test]
fn equidistant_model_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let text = read("ros_plumb_bob.yaml")
        .replace("plumb_bob", "equidistant")
        .replace(
            "cols: 5\n  data: [-0.28, 0.09, 0.0012, -0.0007, -0.011]",
            "cols: 4\n  data: [-0.02, 0.004, -0.001, 0.0002]",
        );
    let msg = load_err(dir.path(), "fisheye.yaml", text.as_bytes());
    assert!(
        msg.contains("'equidistant'") && msg.contains("only plumb_bob and rational_polynomial"),
        "{msg}"
    );
}

#[test]
fn files_that_are_not_yaml_calibrations_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let msg = load_err(
        dir.path(),
        "broken.yaml",
        b"image_width: 640\ncamera_matrix: [1, 2\n  data: ]]\n",
    );
    assert!(msg.contains("not a valid YAML file"), "{msg}");
    let msg = load_err(
        dir.path(),
        "image.png",
        b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR\xff\xfe",
    );
    assert!(msg.contains("not UTF-8"), "{msg}");
    let msg = load_err(dir.path(), "notes.txt", b"just some notes\n");
    assert!(msg.contains("not a camera calibration"), "{msg}");

    let missing = dir.path().join("absent.yaml");
    let err = Calibration::load(&missing).unwrap_err();
    assert!(
        matches!(err, CaptureError::Io { .. }) && err.to_string().contains("absent.yaml"),
        "{err}"
    );
}

#[test]
fn bad_focal_lengths_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let text = read("ros_plumb_bob.yaml").replace("[525.3, 0,", "[-525.3, 0,");
    let msg = load_err(dir.path(), "neg_f.yaml", text.as_bytes());
    assert!(msg.contains("focal lengths fx = -525.3"), "{msg}");
    let text = read("opencv_plumb_bob.yaml").replace("5.2610000000000002e+02", ".inf");
    let msg = load_err(dir.path(), "inf_f.yaml", text.as_bytes());
    assert!(
        msg.contains("focal lengths") && msg.contains("inf"),
        "{msg}"
    );
}
