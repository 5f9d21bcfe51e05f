//! `acch eval --protocol table2`: the paper's table 2. Pose estimation in
//! textured scenes where nobody hands us the mask: recognition (window scan
//! over a cell grid) and segmentation (region growing) find the object, the
//! ACCH pose is estimated on the segmented region.
//!
//! Training: the paper grid (θ in {45, 50, 60, 70, 80, 90} x φ every 10°) on
//! the plain background, frame seed 0. Testing: `n` random poses per
//! background, rendered at the training distance on backgrounds A (wood), B
//! (blue fabric), C (green felt) and `clutter-similar` (distractors painted
//! in the object's own colours; reported as "clutter", one layout per
//! image). Per row: mean segmentation IoU against the true mask (0 when not
//! found), mean |Δφ| and |Δθ| over the estimates made, and the failure rate
//! (|Δθ| > 10° or |Δφ| > 20°, "not found" counts as a failure). Also
//! measured: the failure rate with scale from the segmented region instead
//! of the known distance, the failure rate with the true mask (what the pose
//! stage alone achieves), false detections on the same scenes with the
//! object out of view, and the time of recognition + segmentation.

use super::common;
use super::eval::{FAIL_PHI_DEG, FAIL_THETA_DEG, PAPER_GRID};
use acch_capture::{
    Background, DEFAULT_DISTANCE, Intrinsics, Object, Rendered, Renderer, SceneConfig, ViewPose,
    ViewSpec,
};
use acch_core::IndexImage;
use acch_pose::train::{LabelledView, TrainConfig, build_database, mask_bbox};
use acch_pose::{PoseEstimator, Refinement, phi_error};
use acch_recognition::{Detector, RecognitionModel, RecognitionParams, SECTION};
use acch_segmentation::Segmenter;
use anyhow::{Context, Result, bail};
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Backgrounds of the protocol: (reported name, renderer background).
const BACKGROUNDS: [(&str, &str); 4] = [
    ("A", "A"),
    ("B", "B"),
    ("C", "C"),
    ("clutter", "clutter-similar"),
];

/// Horizontal shift of the principal point that puts the object out of view
/// (the "empty scene" of a test pose).
const OUT_OF_VIEW_PX: f64 = 4000.0;

/// One row of table 2.
#[derive(Clone, Debug, Serialize)]
pub struct Table2Row {
    /// Background name (A, B, C, clutter).
    pub background: String,
    /// Test images.
    pub n: usize,
    /// Mean IoU of the segmentation with the true mask (0 when not found).
    pub iou: f64,
    /// Mean |Δφ| over the estimates made, degrees.
    pub mean_phi_err_deg: f64,
    /// Mean |Δθ| over the estimates made, degrees.
    pub mean_theta_err_deg: f64,
    /// Share of failures (|Δθ| > 10°, |Δφ| > 20°, or not found).
    pub failure_rate: f64,
    /// Images in which the object was not found.
    pub not_found: usize,
    /// Failure rate with the scale taken from the segmented region.
    pub failure_rate_scale_from_roi: f64,
    /// Failure rate of the pose stage alone, with the true mask.
    pub failure_rate_true_mask: f64,
    /// Detections in the same scenes with the object out of view.
    pub false_detections: usize,
    /// Median window score with the object in view.
    pub median_score: f64,
    /// Highest window score with the object out of view.
    pub max_empty_score: f64,
    /// Mean time of recognition + segmentation of one frame, ms.
    pub ms_detect_segment: f64,
    /// Slowest recognition + segmentation, ms.
    pub max_ms_detect_segment: f64,
}

#[derive(Serialize)]
struct Table2Report {
    protocol: &'static str,
    object: String,
    n: usize,
    rows: Vec<Table2Row>,
    threshold: f32,
    train_score: f32,
    ms_quantise: f64,
    ms_detect: f64,
    ms_segment: f64,
    train_seconds: f64,
    total_seconds: f64,
}

/// Runs the table-2 protocol for one object and prints the table; writes
/// the report as JSON when `json` is given.
pub fn table2(
    object: Arc<Object>,
    n: usize,
    seed: u64,
    config: &TrainConfig,
    json: Option<&Path>,
) -> Result<()> {
    if n == 0 {
        bail!("--n must be at least 1");
    }
    let start = Instant::now();
    let plain = common::renderer(object.clone(), Background::default(), seed);
    let grid: ViewSpec = PAPER_GRID.parse()?;
    let train = common::render_views(&plain, &grid.views(DEFAULT_DISTANCE, 0), 0, "train views");
    let labelled: Vec<LabelledView> = train
        .iter()
        .map(|r| common::labelled(r, DEFAULT_DISTANCE))
        .collect();
    let mut db = build_database(object.name(), DEFAULT_DISTANCE as f32, &labelled, config)?;
    let model = RecognitionModel::train(&labelled, &db.palette, &RecognitionParams::default())
        .context("training the recognition model")?;
    db.sections.insert(SECTION.to_owned(), model.to_bytes());
    drop(train);
    let train_seconds = start.elapsed().as_secs_f64();
    let (threshold, train_score) = (model.threshold, model.train_score);

    let intrinsics = Intrinsics::default();
    let (w, h) = (intrinsics.width, intrinsics.height);
    let mut estimator = PoseEstimator::new(db)?;
    let mut detector = Detector::new(model, w, h)?;
    let mut segmenter = Segmenter::new(w, h)?;
    let mut index = IndexImage::default();
    let mut mask = vec![0u8; (w * h) as usize];
    let views = ViewSpec::Random { n }.views(DEFAULT_DISTANCE, seed);
    let scale = Some(estimator.scale_for_distance(DEFAULT_DISTANCE as f32));
    let (mut t_quantise, mut t_detect, mut t_segment, mut frames) = (0f64, 0f64, 0f64, 0usize);
    let mut rows = Vec::new();
    for (name, bg) in BACKGROUNDS {
        let background: Background = bg.parse()?;
        let scenes = render_scenes(&object, background, &views, seed, name)?;
        let (mut sum_iou, mut sum_phi, mut sum_theta) = (0f64, 0f64, 0f64);
        let (mut estimated, mut failures, mut roi_failures, mut true_failures) = (0, 0, 0, 0);
        let (mut not_found, mut false_detections) = (0, 0);
        let (mut ms_sum, mut ms_max) = (0f64, 0f64);
        let (mut scores, mut max_empty) = (Vec::with_capacity(n), 0f32);
        for ((scene, empty), view) in scenes.iter().zip(&views) {
            let fails = |e: Option<acch_pose::Estimate>| match e {
                Some(e) => {
                    (e.theta_deg - view.theta_deg as f32).abs() > FAIL_THETA_DEG
                        || phi_error(e.phi_deg, view.phi_deg as f32) > FAIL_PHI_DEG
                }
                None => true,
            };
            // The object out of view: any detection is a false one.
            estimator
                .database()
                .palette
                .quantise_into(empty.image.as_raw(), w, h, &mut index);
            if detector.detect(&index, scale).is_some() {
                false_detections += 1;
            }
            max_empty = max_empty.max(detector.best_score());

            let t0 = Instant::now();
            estimator
                .database()
                .palette
                .quantise_into(scene.image.as_raw(), w, h, &mut index);
            let t1 = Instant::now();
            let detection = detector.detect(&index, scale);
            let t2 = Instant::now();
            let segment = detection.and_then(|d| segmenter.segment(&index, &detector, &d));
            let t3 = Instant::now();
            let roi = segment.map(|s| {
                mask.copy_from_slice(s.mask);
                s.roi
            });
            t_quantise += (t1 - t0).as_secs_f64();
            t_detect += (t2 - t1).as_secs_f64();
            t_segment += (t3 - t2).as_secs_f64();
            frames += 1;
            let ms = (t3 - t1).as_secs_f64() * 1e3;
            ms_sum += ms;
            ms_max = ms_max.max(ms);
            scores.push(detector.best_score());

            let truth = scene.mask.as_raw();
            if let Some(true_roi) = mask_bbox(truth, w, h) {
                let e = estimator.estimate(&index, Some(truth), true_roi, scale, Refinement::Parabolic);
                true_failures += fails(e) as usize;
            } else {
                true_failures += 1;
            }
            let Some(roi) = roi else {
                not_found += 1;
                failures += 1;
                roi_failures += 1;
                continue;
            };
            sum_iou += iou(&mask, truth);
            let e = estimator.estimate(&index, Some(&mask), roi, scale, Refinement::Parabolic);
            failures += fails(e) as usize;
            if let Some(e) = e {
                sum_phi += phi_error(e.phi_deg, view.phi_deg as f32) as f64;
                sum_theta += (e.theta_deg - view.theta_deg as f32).abs() as f64;
                estimated += 1;
            }
            let e = estimator.estimate(&index, Some(&mask), roi, None, Refinement::Parabolic);
            roi_failures += fails(e) as usize;
        }
        scores.sort_by(f32::total_cmp);
        let nn = views.len() as f64;
        rows.push(Table2Row {
            background: name.to_owned(),
            n: views.len(),
            iou: sum_iou / nn,
            mean_phi_err_deg: sum_phi / estimated.max(1) as f64,
            mean_theta_err_deg: sum_theta / estimated.max(1) as f64,
            failure_rate: failures as f64 / nn,
            not_found,
            failure_rate_scale_from_roi: roi_failures as f64 / nn,
            failure_rate_true_mask: true_failures as f64 / nn,
            false_detections,
            median_score: scores[scores.len() / 2] as f64,
            max_empty_score: max_empty as f64,
            ms_detect_segment: ms_sum / nn,
            max_ms_detect_segment: ms_max,
        });
    }

    let frames = frames.max(1) as f64;
    let report = Table2Report {
        protocol: "table2",
        object: object.name().to_owned(),
        n,
        rows,
        threshold,
        train_score,
        ms_quantise: 1e3 * t_quantise / frames,
        ms_detect: 1e3 * t_detect / frames,
        ms_segment: 1e3 * t_segment / frames,
        train_seconds,
        total_seconds: start.elapsed().as_secs_f64(),
    };
    print_report(&report);
    if let Some(path) = json {
        std::fs::write(path, serde_json::to_string_pretty(&report)? + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn print_report(r: &Table2Report) {
    println!(
        "table2 · {} · {} random poses per background · recognition threshold {:.3} (training score {:.3})",
        r.object, r.n, r.threshold, r.train_score
    );
    println!(
        "{:<10} {:>4} {:>6} {:>9} {:>9} {:>9} {:>6} {:>10} {:>10} {:>7} {:>7}",
        "background", "n", "IoU", "E(phi)", "E(theta)", "failures", "lost", "fail(roi)", "fail(true)", "false+", "ms"
    );
    for row in &r.rows {
        println!(
            "{:<10} {:>4} {:>6.3} {:>8.2}° {:>8.2}° {:>8.1}% {:>6} {:>9.1}% {:>9.1}% {:>7} {:>7.2}",
            row.background,
            row.n,
            row.iou,
            row.mean_phi_err_deg,
            row.mean_theta_err_deg,
            100.0 * row.failure_rate,
            row.not_found,
            100.0 * row.failure_rate_scale_from_roi,
            100.0 * row.failure_rate_true_mask,
            row.false_detections,
            row.ms_detect_segment,
        );
    }
    println!(
        "per frame: quantise {:.2} ms, recognition {:.2} ms, segmentation {:.2} ms · training {:.1} s, total {:.1} s",
        r.ms_quantise, r.ms_detect, r.ms_segment, r.train_seconds, r.total_seconds
    );
    println!(
        "lost = not found; fail(roi) = scale from the segmented region; fail(true) = true mask; false+ = detections with the object out of view"
    );
}

/// Renders each test pose on `background` twice, in parallel: the scene,
/// and the same scene with the object out of view. Clutter layouts change
/// from image to image.
fn render_scenes(
    object: &Arc<Object>,
    background: Background,
    views: &[ViewPose],
    seed: u64,
    name: &str,
) -> Result<Vec<(Rendered, Rendered)>> {
    let bar = common::progress(views.len() as u64, &format!("background {name}"));
    let shared = (!background.has_clutter()).then(|| common::renderer(object.clone(), background, seed));
    let mut far = Intrinsics::default();
    far.cx += OUT_OF_VIEW_PX;
    let out = views
        .par_iter()
        .enumerate()
        .map(|(i, v)| {
            let scene_seed = common::frame_seed(seed, i);
            let own;
            let renderer = match &shared {
                Some(r) => r,
                None => {
                    own = common::renderer(object.clone(), background, scene_seed);
                    &own
                }
            };
            let empty = Renderer::new(
                SceneConfig {
                    intrinsics: far,
                    ..renderer.config().clone()
                },
                if shared.is_some() { seed } else { scene_seed },
            );
            let frame_seed = common::frame_seed(seed, i);
            let r = (renderer.render(v, frame_seed), empty.render(v, frame_seed));
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    Ok(out)
}

/// Intersection over union of two masks (non-zero = set).
fn iou(a: &[u8], b: &[u8]) -> f64 {
    let (mut inter, mut union) = (0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x != 0, y != 0);
        inter += (x && y) as u64;
        union += (x || y) as u64;
    }
    if union == 0 { 0.0 } else { inter as f64 / union as f64 }
}
