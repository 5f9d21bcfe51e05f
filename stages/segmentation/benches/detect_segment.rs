//! Benchmarks of recognition and segmentation on a rendered 640x480 frame:
//! quantisation (for reference, done once per frame by the caller; also
//! with the frame smoothed first), the
//! per-cell counts and their integral (`prepare`), the window scan, the
//! segmentation (and without cutting foreign colours), and recognition +
//! segmentation together, for the fruitbox
//! on background A and among similar-colour clutter.
//!
//! `cargo bench -p acch-segmentation --bench detect_segment` runs them.

use acch_capture::{
    Background, DEFAULT_DISTANCE, Object, Renderer, SceneConfig, ViewPose, ViewSpec,
};
use acch_core::{IndexImage, Palette};
use acch_recognition::{Detector, RecognitionModel};
use acch_segmentation::Segmenter;
use criterion::Criterion;
use std::hint::black_box;
use std::sync::Arc;
use std::time::Duration;

/// The fruitbox's palette and model, trained on the paper's grid with the
/// default configuration (the palette decides how many background pixels
/// the per-cell counting has to visit).
fn train(object: &Arc<Object>) -> (Palette, RecognitionModel) {
    let plain = Renderer::new(SceneConfig::new(object.clone(), Background::default()), 0);
    let t = acch_testkit::train_on_views("fruitbox", &plain, &ViewSpec::training_grid());
    (t.db.palette, t.model)
}

fn main() {
    let object = Arc::new(Object::builtin("fruitbox").unwrap());
    let (palette, model) = train(&object);
    let mut c = Criterion::default()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(30)
        .configure_from_args();
    for (name, bg) in [
        ("A", Background::A),
        ("clutter", Background::ClutterSimilar),
    ] {
        let scene = Renderer::new(SceneConfig::new(object.clone(), bg), 3);
        let frame = scene.render(&ViewPose::new(62.0, 35.0, DEFAULT_DISTANCE).unwrap(), 1);
        let rgb = frame.image.as_raw();
        let mut index = IndexImage::default();
        palette.quantise_into(rgb, 640, 480, &mut index);
        let mut detector = Detector::new(model.clone(), 640, 480).unwrap();
        let mut segmenter = Segmenter::new(640, 480).unwrap();
        let detection = detector
            .detect(&index, Some(1.0))
            .expect("the object is found");
        let owned = index
            .data
            .iter()
            .filter(|&&i| i != acch_core::NOT_OBJECT)
            .count();
        eprintln!(
            "{name}: {owned} of {} pixels have an object colour",
            index.data.len()
        );
        let mut group = c.benchmark_group(format!("640x480_{name}"));
        group.bench_function("quantise", |b| {
            b.iter(|| palette.quantise_into(black_box(rgb), 640, 480, &mut index))
        });
        // What smoothing the frame first costs (`acch train --smoothing
        // binomial`).
        let smoothing = palette
            .clone()
            .with_smoothing(acch_core::Smoothing::Binomial);
        let mut smoothed_index = IndexImage::default();
        group.bench_function("quantise_smoothed", |b| {
            b.iter(|| smoothing.quantise_into(black_box(rgb), 640, 480, &mut smoothed_index))
        });
        group.bench_function("prepare", |b| {
            b.iter(|| detector.prepare(black_box(&index)))
        });
        group.bench_function("scan", |b| b.iter(|| black_box(detector.scan(1.0))));
        group.bench_function("segment", |b| {
            b.iter(|| {
                segmenter
                    .segment_detected(&index, &detector, black_box(&detection))
                    .map(|s| s.area)
            })
        });
        // What cutting foreign colours costs: the same model without the
        // colour peaks it is decided by.
        let mut blind = model.clone();
        blind.colour_peaks = None;
        group.bench_function("segment_without_colour_peaks", |b| {
            b.iter(|| {
                let counts = detector.region_counts(&detection)?;
                segmenter
                    .segment(&index, &counts, &blind, black_box(&detection))
                    .map(|s| s.area)
            })
        });
        group.bench_function("detect+segment", |b| {
            b.iter(|| {
                let d = detector.detect(black_box(&index), Some(1.0))?;
                segmenter
                    .segment_detected(&index, &detector, &d)
                    .map(|s| s.area)
            })
        });
        group.finish();
    }
    c.final_summary();
}
