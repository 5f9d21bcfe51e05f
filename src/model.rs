//! Training an object's whole database: view histograms, the recognition
//! model, and the confidence network trained on rendered scenes whose
//! ground truth labels each estimate reliable or not.

use crate::cmd::common;
use crate::pipeline::Pipeline;
use acch_capture::{Background, Object, ViewSpec};
use acch_confidence::{Kind, Tolerance};
use acch_core::ViewDatabase;
use acch_pose::train::{LabelledView, TrainConfig, build_database};
use acch_recognition::{RecognitionModel, RecognitionParams};
use anyhow::{Context, Result};
use rayon::prelude::*;
use std::sync::Arc;

/// Backgrounds the confidence network is trained on: every kind the
/// evaluations use, so it sees good and bad segmentations alike.
pub const CONFIDENCE_BACKGROUNDS: [&str; 6] =
    ["plain", "A", "B", "C", "clutter", "clutter-similar"];

/// Seeds of confidence-training scenes start here; evaluations use small
/// seeds, so training and evaluation scenes never share a scene or a pose.
pub const CONFIDENCE_SEED_BASE: u64 = 1_000_000;

/// How to render the training views.
#[derive(Clone, Debug)]
pub struct RenderedTraining {
    /// The views (the paper's grid by default).
    pub views: ViewSpec,
    /// Their background.
    pub background: Background,
    /// Camera distance, object bounding radii.
    pub distance: f64,
    /// Seed of the views and the scene.
    pub seed: u64,
}

/// Histograms and recognition model from labelled views.
pub fn train_views(
    object: &str,
    distance: f32,
    views: &[LabelledView<'_>],
    config: &TrainConfig,
) -> Result<ViewDatabase> {
    let mut db = build_database(object, distance, views, config)?;
    let recognition = RecognitionModel::train(views, &db.palette, &RecognitionParams::default())?;
    db.sections
        .insert(acch_recognition::SECTION.to_owned(), recognition.to_bytes());
    Ok(db)
}

/// Renders the training views of `object` and trains histograms and the
/// recognition model.
pub fn train_rendered(
    object: &Arc<Object>,
    config: &TrainConfig,
    training: &RenderedTraining,
) -> Result<ViewDatabase> {
    let views = training.views.views(training.distance, training.seed);
    let renderer = common::renderer(object.clone(), training.background, training.seed);
    let renders = common::render_views(&renderer, &views, training.seed, "train views");
    let labelled: Vec<LabelledView> = renders
        .iter()
        .map(|r| common::labelled(r, training.distance))
        .collect();
    train_views(object.name(), training.distance as f32, &labelled, config)
}

/// One estimate of a confidence-training scene.
pub struct ConfidenceSample {
    /// The four response features.
    pub features: Vec<f32>,
    /// The whole normalised response.
    pub response: Vec<f32>,
    /// Whether the estimate was within the failure thresholds.
    pub reliable: bool,
}

/// Renders `per_background` random-pose scenes on each of
/// [`CONFIDENCE_BACKGROUNDS`] (seeds from `seed_base`), runs the chain
/// without confidence, and labels each estimate by ground truth.
pub fn confidence_samples(
    db: &ViewDatabase,
    object: &Arc<Object>,
    per_background: usize,
    seed_base: u64,
    distance: f64,
) -> Result<Vec<ConfidenceSample>> {
    let params = acch_confidence::FeatureParams::default();
    let tolerance = Tolerance::default();
    let mut samples = Vec::new();
    for (k, name) in CONFIDENCE_BACKGROUNDS.iter().enumerate() {
        let seed = seed_base + k as u64;
        let background: Background = name.parse()?;
        let renderer = common::renderer(object.clone(), background, seed);
        let views = confidence_views(per_background, distance, seed)?;
        let renders = common::render_views(&renderer, &views, seed, name);
        let (w, h) = (renderer_width(&renders), renderer_height(&renders));
        let chunk: Vec<ConfidenceSample> = renders
            .par_iter()
            .map_init(
                || {
                    Pipeline::new(db.clone(), w, h, Some(distance as f32))
                        .map(Pipeline::without_confidence)
                },
                |pipeline, r| -> Result<Option<ConfidenceSample>> {
                    let pipeline = pipeline.as_mut().map_err(|e| anyhow::anyhow!("{e:#}"))?;
                    let result = pipeline.process(r.image.as_raw(), w, h);
                    let Some(e) = result.estimate else {
                        return Ok(None);
                    };
                    let est = pipeline.estimator();
                    let (resp, slices, views) =
                        (est.response(), est.slices(), est.database().views());
                    Ok(Some(ConfidenceSample {
                        features: Kind::Features.input(&params, resp, slices, views)?,
                        response: Kind::Response.input(&params, resp, slices, views)?,
                        reliable: tolerance.reliable(
                            (e.theta_deg, e.phi_deg),
                            (r.truth.theta_deg as f32, r.truth.phi_deg as f32),
                        ),
                    }))
                },
            )
            .collect::<Result<Vec<_>>>()?
            .into_iter()
            .flatten()
            .collect();
        samples.extend(chunk);
    }
    Ok(samples)
}

/// Revision of the default training recipe; part of cached databases'
/// names so that a changed recipe retrains instead of reusing a stale file.
pub const TRAINING_REVISION: u32 = 2;

/// The confidence network's default input, chosen by measurement on the
/// table-2 protocol (README): the whole response separates reliable from
/// unreliable estimates better than the paper's four features.
pub const DEFAULT_CONFIDENCE_KIND: Kind = Kind::Response;

/// Confidence-training scenes per background used by default.
pub const DEFAULT_CONFIDENCE_SCENES: usize = 80;

/// Lowest elevation of confidence-training poses: below the grid's 45°, so
/// the network also sees views the database does not cover and must learn to
/// reject them (a robot's camera is not confined to the grid's range).
pub const CONFIDENCE_MIN_THETA_DEG: f64 = 20.0;

/// `n` poses with θ uniform in [CONFIDENCE_MIN_THETA_DEG, 90], φ in [0, 360).
fn confidence_views(n: usize, distance: f64, seed: u64) -> Result<Vec<acch_capture::ViewPose>> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let theta = rng.random_range(CONFIDENCE_MIN_THETA_DEG..=90.0);
            let phi = rng.random_range(0.0..360.0);
            Ok(acch_capture::ViewPose::new(theta, phi, distance)?)
        })
        .collect()
}

fn renderer_width(renders: &[acch_capture::Rendered]) -> u32 {
    renders.first().map_or(640, |r| r.image.width())
}

fn renderer_height(renders: &[acch_capture::Rendered]) -> u32 {
    renders.first().map_or(480, |r| r.image.height())
}

/// Trains a confidence network of `kind` on `samples` and stores it in `db`.
/// Samples of one class only (every estimate right, or every one wrong)
/// cannot teach it anything: that is an error naming the counts.
pub fn train_confidence(
    db: &mut ViewDatabase,
    samples: &[ConfidenceSample],
    kind: Kind,
    seed: u64,
) -> Result<()> {
    let data: Vec<(Vec<f32>, bool)> = samples
        .iter()
        .map(|s| {
            let input = match kind {
                Kind::Features => s.features.clone(),
                Kind::Response => s.response.clone(),
            };
            (input, s.reliable)
        })
        .collect();
    let mut config = acch_confidence::TrainConfig::new(kind);
    config.seed = seed;
    let bar = common::progress(config.epochs as u64, "confidence");
    let model = acch_confidence::train_with_progress(&data, &config, &mut |epoch, _loss| {
        bar.set_position(epoch as u64)
    })
    .context("training the confidence network")?;
    bar.finish_and_clear();
    model.store(db);
    Ok(())
}

/// The whole database of a rendered object: views, recognition model and,
/// with `confidence = Some((scenes per background, kind))`, the confidence
/// network.
pub fn train_object(
    object: &Arc<Object>,
    config: &TrainConfig,
    training: &RenderedTraining,
    confidence: Option<(usize, Kind)>,
) -> Result<ViewDatabase> {
    let mut db = train_rendered(object, config, training)?;
    if let Some((scenes, kind)) = confidence.filter(|(n, _)| *n > 0) {
        let samples =
            confidence_samples(&db, object, scenes, CONFIDENCE_SEED_BASE, training.distance)?;
        let reliable = samples.iter().filter(|s| s.reliable).count();
        tracing::info!(
            "confidence: {} estimates from {} scenes, {} reliable, {} not",
            samples.len(),
            scenes * CONFIDENCE_BACKGROUNDS.len(),
            reliable,
            samples.len() - reliable
        );
        train_confidence(&mut db, &samples, kind, training.seed)?;
    }
    Ok(db)
}
