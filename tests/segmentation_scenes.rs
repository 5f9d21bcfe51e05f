//! Recognition and segmentation on rendered scenes: the detection lands on
//! the object, empty scenes give "not found", the mask stays on the object
//! in clutter, with the object partly outside the view, with two identical
//! objects in view and at other distances; and the table-2 protocol of
//! `acch eval` writes its report.

use acch_capture::{
    Background, DEFAULT_DISTANCE, Intrinsics, Object, Renderer, SceneConfig, ViewPose, ViewSpec,
};
use acch_core::{IndexImage, ViewDatabase};
use acch_recognition::{Detection, Detector, RecognitionModel, RegionCounts};
use acch_segmentation::Segmenter;
use std::sync::{Arc, OnceLock};

struct Trained {
    object: Arc<Object>,
    db: ViewDatabase,
    model: RecognitionModel,
}

/// A model of the fruitbox from a coarse grid (fast; the protocol uses the
/// paper's grid).
fn fruitbox() -> &'static Trained {
    static T: OnceLock<Trained> = OnceLock::new();
    T.get_or_init(|| {
        let object = Arc::new(Object::builtin("fruitbox").unwrap());
        let r = renderer(&object, Background::default(), 0, 0.0);
        let grid = ViewSpec::Grid {
            thetas_deg: vec![45.0, 60.0, 75.0, 90.0],
            phi_step_deg: 30.0,
        };
        let acch_testkit::Trained { db, model } =
            acch_testkit::train_on_views("fruitbox", &r, &grid);
        Trained { object, db, model }
    })
}

/// A renderer whose principal point is moved right by `shift_px` (the object
/// moves right in the image).
fn renderer(object: &Arc<Object>, background: Background, seed: u64, shift_px: f64) -> Renderer {
    let mut intrinsics = Intrinsics::default();
    intrinsics.cx += shift_px;
    Renderer::new(
        SceneConfig {
            object: object.clone(),
            background,
            intrinsics,
            effects: Default::default(),
            textures: Default::default(),
            occlusion: 0.0,
            occluder: None,
            light_azimuth_deg: 0.0,
        },
        seed,
    )
}

fn view(theta: f64, phi: f64) -> ViewPose {
    ViewPose::new(theta, phi, DEFAULT_DISTANCE).unwrap()
}

fn iou(a: &[u8], b: &[u8]) -> f64 {
    let (mut i, mut u) = (0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        i += (x != 0 && y != 0) as u64;
        u += (x != 0 || y != 0) as u64;
    }
    if u == 0 { 0.0 } else { i as f64 / u as f64 }
}

struct Run {
    detector: Detector,
    segmenter: Segmenter,
    index: IndexImage,
}

impl Run {
    fn new(t: &Trained) -> Self {
        Run {
            detector: Detector::new(t.model.clone(), 640, 480).unwrap(),
            segmenter: Segmenter::new(640, 480).unwrap(),
            index: IndexImage::default(),
        }
    }

    fn detect(&mut self, t: &Trained, rgb: &[u8]) -> Option<Detection> {
        t.db.palette.quantise_into(rgb, 640, 480, &mut self.index);
        self.detector.detect(&self.index, Some(1.0))
    }

    /// Detection and mask (a copy), or `None` when not found.
    fn segment(&mut self, t: &Trained, rgb: &[u8]) -> Option<(Detection, Vec<u8>)> {
        let d = self.detect(t, rgb)?;
        let s = self
            .segmenter
            .segment_detected(&self.index, &self.detector, &d)?;
        Some((d, s.mask.to_vec()))
    }
}

#[test]
fn detection_lands_on_the_object() {
    let t = fruitbox();
    let mut run = Run::new(t);
    for (k, bg) in ["A", "B", "C", "clutter-similar"].iter().enumerate() {
        for (theta, phi) in [(50.0, 15.0), (70.0, 200.0), (88.0, 300.0)] {
            let f = renderer(&t.object, bg.parse().unwrap(), 10 + k as u64, 0.0)
                .render(&view(theta, phi), 1);
            let d = run
                .detect(t, f.image.as_raw())
                .unwrap_or_else(|| panic!("{bg} θ {theta} φ {phi}: not found"));
            let w = d.window;
            let (cx, cy) = (w.x + w.width / 2, w.y + w.height / 2);
            assert!(
                f.mask.get_pixel(cx, cy)[0] != 0,
                "{bg} θ {theta} φ {phi}: window centre ({cx}, {cy}) off the object"
            );
            assert!(!d.truncated);
            assert!(d.score >= d.threshold);
        }
    }
}

/// What recognition publishes for segmentation (the search area's counts
/// and the ring's sums) segments exactly as the detector's own counts, and
/// is a small part of the grid's counts.
#[test]
fn published_region_counts_segment_rendered_scenes_exactly_and_are_small() {
    let t = fruitbox();
    let mut run = Run::new(t);
    let mut other = Segmenter::new(640, 480).unwrap();
    for (k, bg) in ["A", "B", "C", "clutter-similar"].iter().enumerate() {
        for (theta, phi) in [(50.0, 15.0), (88.0, 300.0)] {
            let f = renderer(&t.object, bg.parse().unwrap(), 30 + k as u64, 0.0)
                .render(&view(theta, phi), 3);
            let d = run.detect(t, f.image.as_raw()).expect("found");
            let own = run.detector.region_counts(&d).expect("prepared");
            let layout = run.detector.count_layout();
            let (gx, gy) = layout.grid();
            let mut bytes = vec![0u8; RegionCounts::published_len(layout, own.search())];
            assert!(own.publish(&mut bytes));
            let all = RegionCounts::published_len(layout, layout.all_cells());
            eprintln!(
                "{bg} θ {theta} φ {phi}: {} of {all} bytes ({} cells of {})",
                bytes.len(),
                own.search().width() * own.search().height(),
                gx * gy
            );
            assert!(
                bytes.len() * 3 < all,
                "{bg}: {} of {all} bytes",
                bytes.len()
            );
            let published = RegionCounts::from_bytes(layout, own.search(), &bytes).unwrap();
            let a = run
                .segmenter
                .segment(&run.index, &own, &t.model, &d)
                .expect("segmented");
            let b = other
                .segment(&run.index, &published, &t.model, &d)
                .expect("segmented");
            assert_eq!((a.roi, a.area), (b.roi, b.area), "{bg} θ {theta} φ {phi}");
            assert!(a.mask == b.mask, "{bg} θ {theta} φ {phi}: masks differ");
        }
    }
}

#[test]
fn empty_scenes_are_not_found() {
    let t = fruitbox();
    let mut run = Run::new(t);
    for (k, bg) in ["plain", "A", "B", "C", "clutter", "clutter-similar"]
        .iter()
        .enumerate()
    {
        for phi in [0.0, 120.0, 240.0] {
            // The camera looks 4000 px to the side of the object.
            let f = renderer(&t.object, bg.parse().unwrap(), 20 + k as u64, 4000.0)
                .render(&view(55.0, phi), 2);
            assert!(f.truth.bbox.is_none(), "the object is out of view");
            let d = run.detect(t, f.image.as_raw());
            assert!(
                d.is_none(),
                "{bg} φ {phi}: found {d:?} in an empty scene (best {})",
                run.detector.best_score()
            );
        }
    }
    // A uniform frame in one of the object's own colours is no object either.
    let c = t.db.palette.centre_rgb()[0];
    let rgb: Vec<u8> = (0..640 * 480).flat_map(|_| c).collect();
    assert!(
        run.detect(t, &rgb).is_none(),
        "uniform frame found (best {})",
        run.detector.best_score()
    );
}

#[test]
fn the_mask_stays_on_the_object_in_clutter() {
    let t = fruitbox();
    let mut run = Run::new(t);
    let views = ViewSpec::Random { n: 12 }.views(DEFAULT_DISTANCE, 7);
    let mut ious = Vec::new();
    for (i, v) in views.iter().enumerate() {
        // A new layout of similar-colour distractors per image.
        let f = renderer(&t.object, Background::ClutterSimilar, 100 + i as u64, 0.0)
            .render(v, i as u64);
        let (_, mask) = run.segment(t, f.image.as_raw()).expect("found");
        ious.push(iou(&mask, f.mask.as_raw()));
    }
    let mean = ious.iter().sum::<f64>() / ious.len() as f64;
    let min = ious.iter().copied().fold(1.0, f64::min);
    eprintln!("clutter IoU mean {mean:.3}, min {min:.3}");
    assert!(
        mean >= 0.9 && min >= 0.7,
        "IoU mean {mean:.3}, min {min:.3}: {ious:.2?}"
    );
}

#[test]
fn an_object_partly_outside_the_view_is_found_and_segmented() {
    let t = fruitbox();
    let mut run = Run::new(t);
    // The object's centre 20 px inside the right border: about half of it
    // is out of view.
    for (theta, phi) in [(60.0, 30.0), (80.0, 250.0)] {
        let f = renderer(&t.object, Background::A, 3, 300.0).render(&view(theta, phi), 3);
        let visible = f.mask.as_raw().iter().filter(|&&m| m != 0).count();
        assert!(visible > 3000, "{visible} visible pixels");
        let (d, mask) = run.segment(t, f.image.as_raw()).expect("found");
        assert!(d.truncated, "{d:?}");
        let io = iou(&mask, f.mask.as_raw());
        eprintln!("partly outside θ {theta} φ {phi}: {visible} px visible, IoU {io:.3}, {d:?}");
        assert!(io >= 0.8, "θ {theta} φ {phi}: IoU {io:.3}");
    }
}

#[test]
fn with_two_identical_objects_the_mask_covers_one() {
    let t = fruitbox();
    let mut run = Run::new(t);
    for (theta, phi) in [(55.0, 40.0), (75.0, 160.0)] {
        let v = view(theta, phi);
        let left = renderer(&t.object, Background::C, 4, -170.0).render(&v, 4);
        let right = renderer(&t.object, Background::C, 4, 170.0).render(&v, 4);
        // Paste the right object into the left frame.
        let mut rgb = left.image.as_raw().clone();
        let rm = right.mask.as_raw();
        for (i, &m) in rm.iter().enumerate() {
            if m != 0 {
                rgb[3 * i..3 * i + 3].copy_from_slice(&right.image.as_raw()[3 * i..3 * i + 3]);
            }
        }
        let lm: Vec<u8> = left
            .mask
            .as_raw()
            .iter()
            .zip(rm)
            .map(|(&l, &r)| if r != 0 { 0 } else { l })
            .collect();
        let (_, mask) = run.segment(t, &rgb).expect("found");
        let (a, b) = (iou(&mask, &lm), iou(&mask, rm));
        eprintln!("two objects θ {theta} φ {phi}: IoU {a:.3} / {b:.3}");
        assert!(a.max(b) >= 0.85, "θ {theta} φ {phi}: IoU {a:.3} / {b:.3}");
        assert!(
            a.min(b) < 0.05,
            "θ {theta} φ {phi}: the mask spans both objects ({a:.3} / {b:.3})"
        );
    }
}

#[test]
fn other_distances_work_with_the_known_scale_and_without_it() {
    let t = fruitbox();
    let mut run = Run::new(t);
    for distance in [3.8, 7.0] {
        let v = ViewPose::new(65.0, 120.0, distance).unwrap();
        let f = renderer(&t.object, Background::C, 5, 0.0).render(&v, 5);
        let img = t.db.palette.quantise(f.image.as_raw(), 640, 480);
        let scale = (DEFAULT_DISTANCE / distance) as f32;
        for s in [Some(scale), None] {
            let d = run
                .detector
                .detect(&img, s)
                .unwrap_or_else(|| panic!("distance {distance}, scale {s:?}: not found"));
            let seg = run
                .segmenter
                .segment_detected(&img, &run.detector, &d)
                .expect("segmented");
            let io = iou(seg.mask, f.mask.as_raw());
            eprintln!("distance {distance} scale {s:?}: IoU {io:.3}");
            let floor = if s.is_some() { 0.9 } else { 0.8 };
            assert!(io >= floor, "distance {distance}, scale {s:?}: IoU {io:.3}");
        }
    }
}

/// `acch eval --protocol table2` end to end, on a few images.
#[test]
fn the_table2_protocol_writes_its_report() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("table2.json");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_acch"))
        .args([
            "eval",
            "--protocol",
            "table2",
            "--object",
            "fruitbox",
            "--n",
            "3",
            "--json",
        ])
        .arg(&json)
        .env("RUST_LOG", "warn")
        .output()
        .expect("run acch");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["protocol"], "table2");
    assert_eq!(report["object"], "fruitbox");
    let rows = report["rows"].as_array().unwrap();
    let names: Vec<&str> = rows
        .iter()
        .map(|r| r["background"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["A", "B", "C", "clutter"]);
    for r in rows {
        assert_eq!(r["n"], 3);
        assert!(r["iou"].as_f64().unwrap() > 0.8, "{r}");
        assert_eq!(r["not_found"], 0, "{r}");
    }
}
