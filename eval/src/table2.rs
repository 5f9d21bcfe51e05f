//! The paper's table 2: pose estimation in textured scenes where nobody
//! hands us the mask. The deployed chain runs on each scene: recognition
//! (window scan over a cell grid) and segmentation (region growing) find
//! the object, the pose stage estimates on the segmented region, the
//! confidence stage accepts or rejects.
//!
//! Training: the paper grid on the plain background, frame seed 0; the
//! confidence network on scenes with seeds disjoint from the test scenes.
//! Testing: `n` random poses per background, at the training distance, on
//! backgrounds A (wood), B (blue fabric), C (green felt) and
//! `clutter-similar` (distractors in the object's own colours; reported as
//! "clutter", one layout per image). Per row: mean segmentation IoU against
//! the true mask (0 when not found), mean |Δφ| and |Δθ| over the estimates
//! made, and the failure rate (the paper's rule; "not found" fails). Also
//! measured: the failure rate with scale from the segmented region instead
//! of the known distance, with the true mask (what the pose stage alone
//! achieves), false detections on the same scenes with the object out of
//! view, and the time of recognition + segmentation.

use crate::protocol::{self, fails};
use crate::{EvalError, write_json};
use acch_capture::{DEFAULT_DISTANCE, Intrinsics, Object, TextureSet, ViewSpec};
use acch_pipeline::stages::{Pose, Segmented};
use acch_pipeline::wire::{Outcome, StageId};
use acch_pipeline::{Hop, Stage, StageSettings};
use acch_pose::phi_error;
use acch_pose::train::TrainConfig;
use acch_recognition::RecognitionModel;
use acch_train::confidence::{
    self, ConfidenceChoice, ConfidenceScenes, DEFAULT_CONFIDENCE_SCENES, kind_name,
};
use acch_train::views::{RenderedTraining, train_rendered};
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

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
    /// Share of failures (the paper's rule, or not found).
    pub failure_rate: f64,
    /// Images in which the object was not found.
    pub not_found: usize,
    /// Share of images whose estimate the confidence network accepted.
    pub accepted_rate: f64,
    /// Mean |Δφ| over accepted estimates, degrees.
    pub acc_mean_phi_err_deg: f64,
    /// Mean |Δθ| over accepted estimates, degrees.
    pub acc_mean_theta_err_deg: f64,
    /// Failure rate among accepted estimates.
    pub acc_failure_rate: f64,
    /// Failure rate with the scale taken from the segmented region.
    pub failure_rate_scale_from_roi: f64,
    /// Failure rate of the pose stage alone, with the true mask.
    pub failure_rate_true_mask: f64,
    /// Detections in the same scenes with the object out of view.
    pub false_detections: usize,
    /// Median window score with the object in view.
    pub median_score: f64,
    /// Lowest window score with the object in view.
    pub min_score: f64,
    /// Highest window score with the object out of view.
    pub max_empty_score: f64,
    /// Mean time of recognition + segmentation of one frame, ms.
    pub ms_detect_segment: f64,
    /// Slowest recognition + segmentation, ms.
    pub max_ms_detect_segment: f64,
}

/// Confidence-network results over every estimate of the protocol, for one
/// kind of network input.
#[derive(Clone, Debug, Serialize)]
pub struct ConfidenceSummary {
    /// "features" (R_phi, D_phi, R_theta, D_theta) or "response".
    pub input: String,
    /// Area under the ROC curve of confidence against reliability.
    pub roc_auc: f64,
    /// Share of estimates accepted at the threshold.
    pub accepted_rate: f64,
    /// Failure rate among accepted estimates.
    pub acc_failure_rate: f64,
    /// Expected calibration error over 10 bins.
    pub calibration_error: f64,
}

/// Table 2's report.
#[derive(Serialize, Debug)]
pub struct Table2Report {
    /// "table2".
    pub protocol: &'static str,
    /// The object.
    pub object: String,
    /// Test poses per background.
    pub n: usize,
    /// The table textures of the test scenes (`held-out`: none of the
    /// confidence network's training scenes shows them).
    pub textures: String,
    /// One row per background.
    pub rows: Vec<Table2Row>,
    /// How the deployed network's input was chosen, on validation scenes.
    pub confidence_choice: ConfidenceChoice,
    /// Both network inputs, over every estimate of every row (the chosen
    /// one first).
    pub confidence: Vec<ConfidenceSummary>,
    /// The network's threshold.
    pub confidence_threshold: f32,
    /// Recognition's threshold.
    pub threshold: f32,
    /// Recognition's score on its training views.
    pub train_score: f32,
    /// Mean recognition time per frame (quantise + scan), ms.
    pub ms_detect: f64,
    /// Mean segmentation time per frame, ms.
    pub ms_segment: f64,
    /// Training time, s.
    pub train_seconds: f64,
    /// Time of the whole protocol, s.
    pub total_seconds: f64,
    /// Reliability bins of both networks (for the diagram).
    #[serde(skip)]
    pub reliability: Vec<(String, Vec<acch_confidence::Bin>)>,
}

/// Options of table 2.
#[derive(Clone, Copy, Debug)]
pub struct Table2Options {
    /// Random test poses per background.
    pub n: usize,
    /// Seed of the test poses and scenes.
    pub seed: u64,
    /// The table textures of the test scenes: held out from the confidence
    /// network's training scenes, or the very ones it was trained on.
    pub textures: TextureSet,
    /// The training views lit from this many directions around the
    /// vertical and half the confidence scenes from a turned one (1: the
    /// training light only, the default recipe).
    pub light_directions: usize,
}

/// The window scan's best score on the last frame `chain` processed.
fn best_score(chain: &acch_pipeline::Chain) -> f32 {
    let recognition = chain.stages().recognition.last_used();
    recognition.detector().best_score()
}

/// Runs table 2 for `object`.
pub fn table2(
    object: Arc<Object>,
    options: &Table2Options,
    config: &TrainConfig,
) -> Result<Table2Report, EvalError> {
    let Table2Options {
        n,
        seed,
        textures,
        light_directions,
    } = *options;
    if n == 0 {
        return Err(EvalError::Input("--n must be at least 1".into()));
    }
    let start = Instant::now();
    let training = RenderedTraining {
        light_directions,
        ..RenderedTraining::default()
    };
    let mut db = train_rendered(&object, config, &training)?;
    // The deployed recipe: both inputs trained on the confidence-training
    // scenes, the one with the higher AUC on the validation scenes kept;
    // the other is measured beside it.
    let (choice, model, alt_model) = confidence::choose_confidence_input(
        &db,
        &object,
        DEFAULT_CONFIDENCE_SCENES,
        DEFAULT_DISTANCE,
        ConfidenceScenes {
            light_turned: light_directions > 1,
            ..ConfidenceScenes::default()
        },
        0,
    )?;
    model.store(&mut db);
    let recognition = RecognitionModel::from_database(&db)?
        .ok_or_else(|| EvalError::Input("the trained database has no recognition model".into()))?;
    let train_seconds = start.elapsed().as_secs_f64();

    let k = Intrinsics::default();
    let (w, h) = (k.width, k.height);
    let mut chain = protocol::chain(&db)?;
    let conf_threshold = chain.stages().confidence.sharp().threshold().unwrap_or(0.0);
    let known = StageSettings {
        width: w,
        height: h,
        distance_m: Some(db.train_distance_m as f64),
        unrated: true,
        roll_search_deg: 0.0,
        light_search: 0,
        verify_shape: true,
    };
    // The same pose stage on the true mask, and on the segmented region
    // with the scale read off it.
    let mut true_pose = Pose::new(&db, &known)?;
    let mut roi_pose = Pose::new(
        &db,
        &StageSettings {
            distance_m: None,
            ..known
        },
    )?;
    let mut region = vec![0u8; 2 * w as usize * h as usize];
    let mut response = vec![0u8; true_pose.max_payload()];
    let mut mask = Vec::new();
    let views = ViewSpec::Random { n }.views(DEFAULT_DISTANCE, seed);
    let (mut t_detect, mut t_segment, mut frames) = (0f64, 0f64, 0usize);
    let mut rows = Vec::new();
    // (default confidence, alternative confidence, reliable) per estimate.
    let mut rated: Vec<(f32, f32, bool)> = Vec::new();
    let estimate_of = |o: Result<Outcome<acch_pipeline::stages::PoseEstimate>, _>| match o {
        Ok(Outcome::Done(e)) => Some((e.theta_deg, e.phi_deg)),
        _ => None,
    };
    let mut sequence = 0u64;
    for (name, background) in protocol::backgrounds() {
        let scenes = protocol::render_scenes(
            &object,
            (background, textures),
            &views,
            seed,
            name,
            Some(OUT_OF_VIEW_PX),
        );
        let (mut sum_iou, mut sum_phi, mut sum_theta) = (0f64, 0f64, 0f64);
        let (mut estimated, mut failures, mut roi_failures, mut true_failures) = (0, 0, 0, 0);
        let (mut not_found, mut false_detections) = (0, 0);
        let (mut accepted, mut acc_failures, mut acc_phi, mut acc_theta) =
            (0usize, 0usize, 0f64, 0f64);
        let (mut ms_sum, mut ms_max) = (0f64, 0f64);
        let (mut scores, mut max_empty) = (Vec::with_capacity(n), 0f32);
        for ((scene, empty), view) in scenes.iter().zip(&views) {
            let empty = empty
                .as_ref()
                .expect("rendered with the object out of view");
            let truth = (view.theta_deg as f32, view.phi_deg as f32);
            let fails_or_none = |e: Option<(f32, f32)>| e.is_none_or(|e| fails(e, truth));
            // The object out of view: any detection is a false one.
            let out = chain.process(
                &protocol::frame_of(empty, sequence, false, object.radius_m()),
                empty.image.as_raw(),
            );
            sequence += 1;
            false_detections += out.detection().done().is_some() as usize;
            max_empty = max_empty.max(best_score(&chain));

            let out = chain.process(
                &protocol::frame_of(scene, sequence, false, object.radius_m()),
                scene.image.as_raw(),
            );
            sequence += 1;
            let trail = out.envelope().trail;
            let (rec_ns, seg_ns) = (
                trail.process_ns(StageId::Recognition),
                trail.process_ns(StageId::Segmentation),
            );
            t_detect += rec_ns as f64 / 1e9;
            t_segment += seg_ns as f64 / 1e9;
            frames += 1;
            let ms = (rec_ns + seg_ns) as f64 / 1e6;
            ms_sum += ms;
            ms_max = ms_max.max(ms);
            scores.push(best_score(&chain));

            let truth_mask = scene.mask.as_raw();
            let indices = chain
                .last_recognition()
                .map(|r| r.indices.data)
                .ok_or_else(|| EvalError::Input("recognition published no indices".into()))?;
            let given = Segmented::from_mask(*out.envelope(), truth_mask, indices, w, &mut region)
                .map_err(|f| EvalError::Input(format!("true mask: {f}")))?;
            let true_estimate = given.and_then(|header| {
                estimate_of(true_pose.process(
                    &header,
                    &region,
                    scene.image.as_raw(),
                    &mut response,
                ))
            });
            true_failures += fails_or_none(true_estimate) as usize;
            let Some(segment) = chain.last_region() else {
                not_found += 1;
                failures += 1;
                roi_failures += 1;
                continue;
            };
            segment.frame_mask(w, h, &mut mask);
            sum_iou += protocol::mask_iou(&mask, truth_mask);
            let estimate = out.pose().done();
            let failed = fails_or_none(estimate.map(|e| (e.theta_deg, e.phi_deg)));
            failures += failed as usize;
            if let Some(e) = estimate {
                let (dphi, dtheta) = (
                    phi_error(e.phi_deg, truth.1) as f64,
                    (e.theta_deg - truth.0).abs() as f64,
                );
                sum_phi += dphi;
                sum_theta += dtheta;
                estimated += 1;
                if let Some(v) = out.rating().verdict() {
                    let est = chain.stages().pose.last_used().estimator();
                    let alt = alt_model.rate(est.response(), est.slices(), est.database().views());
                    rated.push((v.confidence, alt, !failed));
                    if v.accepted {
                        accepted += 1;
                        acc_failures += failed as usize;
                        acc_phi += dphi;
                        acc_theta += dtheta;
                    }
                }
            }
            let segmented = out.rated.posed.segmented;
            let e = estimate_of(roi_pose.process(
                &segmented,
                chain.payload(StageId::Segmentation),
                scene.image.as_raw(),
                &mut response,
            ));
            roi_failures += fails_or_none(e) as usize;
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
            accepted_rate: accepted as f64 / nn,
            acc_mean_phi_err_deg: acc_phi / accepted.max(1) as f64,
            acc_mean_theta_err_deg: acc_theta / accepted.max(1) as f64,
            acc_failure_rate: acc_failures as f64 / accepted.max(1) as f64,
            failure_rate_scale_from_roi: roi_failures as f64 / nn,
            failure_rate_true_mask: true_failures as f64 / nn,
            false_detections,
            median_score: scores[scores.len() / 2] as f64,
            min_score: scores[0] as f64,
            max_empty_score: max_empty as f64,
            ms_detect_segment: ms_sum / nn,
            max_ms_detect_segment: ms_max,
        });
    }

    let labels: Vec<bool> = rated.iter().map(|r| r.2).collect();
    let summarise = |input: &str, scores: &[f32]| {
        let acceptance = acch_confidence::Acceptance::new(scores, &labels, conf_threshold);
        ConfidenceSummary {
            input: input.to_owned(),
            roc_auc: acch_confidence::roc_auc(scores, &labels),
            accepted_rate: acceptance.acceptance_rate(),
            acc_failure_rate: acceptance.accepted_failure_rate(),
            calibration_error: acch_confidence::expected_calibration_error(
                &acch_confidence::reliability_bins(scores, &labels, 10),
            ),
        }
    };
    let main_scores: Vec<f32> = rated.iter().map(|r| r.0).collect();
    let alt_scores: Vec<f32> = rated.iter().map(|r| r.1).collect();
    let (main_name, alt_name) = (kind_name(model.kind()), kind_name(alt_model.kind()));
    let frames = frames.max(1) as f64;
    Ok(Table2Report {
        protocol: "table2",
        object: object.name().to_owned(),
        n,
        textures: textures.to_string(),
        rows,
        confidence_choice: choice,
        confidence: vec![
            summarise(main_name, &main_scores),
            summarise(alt_name, &alt_scores),
        ],
        confidence_threshold: conf_threshold,
        threshold: recognition.threshold,
        train_score: recognition.train_score,
        ms_detect: 1e3 * t_detect / frames,
        ms_segment: 1e3 * t_segment / frames,
        train_seconds,
        total_seconds: start.elapsed().as_secs_f64(),
        reliability: vec![
            (
                main_name.to_owned(),
                acch_confidence::reliability_bins(&main_scores, &labels, 10),
            ),
            (
                alt_name.to_owned(),
                acch_confidence::reliability_bins(&alt_scores, &labels, 10),
            ),
        ],
    })
}

impl Table2Report {
    /// Writes the report as JSON.
    pub fn write_json(&self, path: &Path) -> Result<(), EvalError> {
        write_json(path, self)
    }

    /// Draws the confidence reliability diagram of both networks.
    pub fn write_reliability(&self, path: &Path) -> Result<(), EvalError> {
        let series: Vec<(String, Vec<acch_viz::plot::ReliabilityBin>)> = self
            .reliability
            .iter()
            .map(|(name, bins)| {
                (
                    name.clone(),
                    bins.iter()
                        .map(|b| acch_viz::plot::ReliabilityBin {
                            mean_confidence: b.mean_confidence,
                            accuracy: b.accuracy,
                            count: b.count,
                        })
                        .collect(),
                )
            })
            .collect();
        let refs: Vec<(&str, &[acch_viz::plot::ReliabilityBin])> = series
            .iter()
            .map(|(n, b)| (n.as_str(), b.as_slice()))
            .collect();
        acch_viz::plot::reliability_diagram(
            path,
            &format!("{}: confidence reliability (table2 estimates)", self.object),
            &refs,
        )?;
        Ok(())
    }

    /// Prints the table.
    pub fn print(&self) {
        let r = self;
        println!(
            "table2 · {} · {} random poses per background, {} table textures · recognition threshold {:.3} (training score {:.3}) · confidence threshold {}",
            r.object, r.n, r.textures, r.threshold, r.train_score, r.confidence_threshold
        );
        println!(
            "{:<10} {:>4} {:>6} {:>8} {:>8} {:>8} {:>5} | {:>8} {:>8} {:>8} {:>8} | {:>9} {:>9} {:>6} {:>6}",
            "background",
            "n",
            "IoU",
            "E(phi)",
            "E(theta)",
            "fail",
            "lost",
            "E(phi)",
            "E(theta)",
            "fail",
            "accept",
            "fail(roi)",
            "fail(true)",
            "false+",
            "ms"
        );
        for row in &r.rows {
            println!(
                "{:<10} {:>4} {:>6.3} {:>7.2}° {:>7.2}° {:>7.1}% {:>5} | {:>7.2}° {:>7.2}° {:>7.1}% {:>7.1}% | {:>8.1}% {:>8.1}% {:>6} {:>6.2}",
                row.background,
                row.n,
                row.iou,
                row.mean_phi_err_deg,
                row.mean_theta_err_deg,
                100.0 * row.failure_rate,
                row.not_found,
                row.acc_mean_phi_err_deg,
                row.acc_mean_theta_err_deg,
                100.0 * row.acc_failure_rate,
                100.0 * row.accepted_rate,
                100.0 * row.failure_rate_scale_from_roi,
                100.0 * row.failure_rate_true_mask,
                row.false_detections,
                row.ms_detect_segment,
            );
        }
        println!("{}", r.confidence_choice);
        for c in &r.confidence {
            println!(
                "confidence from {:<8}: ROC AUC {:.3}, accepted {:.1} %, failures among accepted {:.1} %, calibration error {:.3}",
                c.input,
                c.roc_auc,
                100.0 * c.accepted_rate,
                100.0 * c.acc_failure_rate,
                c.calibration_error
            );
        }
        println!(
            "per frame: recognition (incl. quantise) {:.2} ms, segmentation {:.2} ms · training {:.1} s, total {:.1} s",
            r.ms_detect, r.ms_segment, r.train_seconds, r.total_seconds
        );
        let min_in = r
            .rows
            .iter()
            .map(|x| x.min_score)
            .fold(f64::INFINITY, f64::min);
        let max_out = r.rows.iter().map(|x| x.max_empty_score).fold(0.0, f64::max);
        let max_ms = r
            .rows
            .iter()
            .map(|x| x.max_ms_detect_segment)
            .fold(0.0, f64::max);
        println!(
            "window scores: object in view >= {min_in:.3}, out of view <= {max_out:.3} (threshold {:.3}, found from {:.3}) · slowest recognition + segmentation {max_ms:.2} ms",
            r.threshold,
            acch_recognition::MIN_FOUND_MARGIN * r.threshold
        );
        println!(
            "left: all estimates; right of |: accepted by the confidence network. lost = not found; fail(roi) = scale from the segmented region; fail(true) = true mask; false+ = detections with the object out of view"
        );
    }
}
