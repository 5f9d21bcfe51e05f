//! The training recipe: an object's whole database (view histograms, the
//! recognition model, and the confidence network trained on rendered
//! scenes whose ground truth labels each estimate reliable or not), from a
//! rendered object or a folder of labelled images, and the cached default
//! database `acch run` uses.

use crate::EvalError;
use crate::protocol::{self, PAPER_GRID};
use acch_capture::{Background, DEFAULT_DISTANCE, Object, ViewPose, ViewSpec};
use acch_confidence::Kind;
use acch_core::ViewDatabase;
use acch_pipeline::stages::{Confidence, Stages};
use acch_pipeline::{Chain, StageSettings};
use acch_pose::train::{LabelledView, TrainConfig, build_database};
use acch_recognition::{RecognitionModel, RecognitionParams};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Backgrounds the confidence network is trained on: every kind the
/// evaluations use, so it sees good and bad segmentations alike.
pub const CONFIDENCE_BACKGROUNDS: [&str; 6] =
    ["plain", "A", "B", "C", "clutter", "clutter-similar"];

/// Seeds of confidence-training scenes start here; evaluations use small
/// seeds, so training and evaluation scenes never share a scene or a pose.
pub const CONFIDENCE_SEED_BASE: u64 = 1_000_000;

/// Revision of the default training recipe; part of cached databases'
/// names so that a changed recipe retrains instead of reusing a stale file.
pub const TRAINING_REVISION: u32 = 3;

/// The confidence network's default input (see `docs/accuracy.md` for how
/// it was chosen).
pub const DEFAULT_CONFIDENCE_KIND: Kind = Kind::Response;

/// Confidence-training scenes per background used by default.
pub const DEFAULT_CONFIDENCE_SCENES: usize = 80;

/// Lowest elevation of confidence-training poses: below the grid's 45°, so
/// the network also sees views the database does not cover and must learn
/// to reject them (a robot's camera is not confined to the grid's range).
pub const CONFIDENCE_MIN_THETA_DEG: f64 = 20.0;

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

impl Default for RenderedTraining {
    /// The paper's grid on the plain background at the default distance.
    fn default() -> Self {
        RenderedTraining {
            views: PAPER_GRID.parse().expect("the paper grid parses"),
            background: Background::default(),
            distance: DEFAULT_DISTANCE,
            seed: 0,
        }
    }
}

/// Histograms and recognition model from labelled views.
pub fn train_views(
    object: &str,
    distance: f32,
    views: &[LabelledView<'_>],
    config: &TrainConfig,
) -> Result<ViewDatabase, EvalError> {
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
) -> Result<ViewDatabase, EvalError> {
    let views = training.views.views(training.distance, training.seed);
    let renderer = protocol::renderer(object.clone(), training.background, training.seed);
    let renders = protocol::render_views(&renderer, &views, training.seed, "train views");
    let labelled: Vec<LabelledView> = renders
        .iter()
        .map(|r| protocol::labelled(r, training.distance))
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

/// The chain of `db`'s stages with the confidence stage unrated, whatever
/// the database holds: what the network's training data is collected with.
pub fn unrated_chain(
    db: &ViewDatabase,
    width: u32,
    height: u32,
    distance: f64,
) -> Result<Chain, EvalError> {
    let settings = StageSettings {
        width,
        height,
        distance: Some(distance),
        unrated: true,
    };
    let mut stages = Stages::new(db, &settings)?;
    stages.confidence = Confidence::unrated(db);
    Ok(Chain::new(stages))
}

/// Renders `per_background` random-pose scenes on each of
/// [`CONFIDENCE_BACKGROUNDS`] (seeds from `seed_base`), runs the chain
/// unrated, and labels each estimate by ground truth.
pub fn confidence_samples(
    db: &ViewDatabase,
    object: &Arc<Object>,
    per_background: usize,
    seed_base: u64,
    distance: f64,
) -> Result<Vec<ConfidenceSample>, EvalError> {
    let params = acch_confidence::FeatureParams::default();
    let mut samples = Vec::new();
    for (k, name) in CONFIDENCE_BACKGROUNDS.iter().enumerate() {
        let seed = seed_base + k as u64;
        let background: Background = name.parse()?;
        let renderer = protocol::renderer(object.clone(), background, seed);
        let views = confidence_views(per_background, distance, seed)?;
        let renders = protocol::render_views(&renderer, &views, seed, name);
        let (w, h) = renders.first().map_or((640, 480), |r| r.image.dimensions());
        let chunk: Vec<ConfidenceSample> = renders
            .par_iter()
            .enumerate()
            .map_init(
                || unrated_chain(db, w, h, distance),
                |chain, (i, r)| -> Result<Option<ConfidenceSample>, EvalError> {
                    let chain = chain
                        .as_mut()
                        .map_err(|e| EvalError::Worker(e.to_string()))?;
                    let out =
                        chain.process(&protocol::frame_of(r, i as u64, false), r.image.as_raw());
                    let Some(e) = out.pose().done() else {
                        return Ok(None);
                    };
                    let est = chain.stages().pose.estimator();
                    let (resp, slices, views) =
                        (est.response(), est.slices(), est.database().views());
                    Ok(Some(ConfidenceSample {
                        features: Kind::Features.input(&params, resp, slices, views)?,
                        response: Kind::Response.input(&params, resp, slices, views)?,
                        reliable: !protocol::fails(
                            (e.theta_deg, e.phi_deg),
                            (r.truth.theta_deg as f32, r.truth.phi_deg as f32),
                        ),
                    }))
                },
            )
            .collect::<Result<Vec<_>, _>>()?
            .into_iter()
            .flatten()
            .collect();
        samples.extend(chunk);
    }
    Ok(samples)
}

/// `n` poses with θ uniform in [CONFIDENCE_MIN_THETA_DEG, 90], φ in [0, 360).
fn confidence_views(n: usize, distance: f64, seed: u64) -> Result<Vec<ViewPose>, EvalError> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let theta = rng.random_range(CONFIDENCE_MIN_THETA_DEG..=90.0);
            let phi = rng.random_range(0.0..360.0);
            Ok(ViewPose::new(theta, phi, distance)?)
        })
        .collect()
}

/// Trains a confidence network of `kind` on `samples` and stores it in
/// `db`. Samples of one class only (every estimate right, or every one
/// wrong) cannot teach it anything: that is an error naming the counts.
pub fn train_confidence(
    db: &mut ViewDatabase,
    samples: &[ConfidenceSample],
    kind: Kind,
    seed: u64,
) -> Result<(), EvalError> {
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
    let bar = protocol::progress(config.epochs as u64, "confidence");
    let model = acch_confidence::train_with_progress(&data, &config, &mut |epoch, _loss| {
        bar.set_position(epoch as u64)
    })?;
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
) -> Result<ViewDatabase, EvalError> {
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

/// Trains from `DIR/labels.csv` and the images (and masks) it names. Views
/// without a mask use their bounding box, or the whole image.
pub fn train_from_folder(dir: &Path, config: &TrainConfig) -> Result<ViewDatabase, EvalError> {
    let labels = dir.join("labels.csv");
    let rows = acch_capture::labels::read_labels(&labels)?;
    if rows.is_empty() {
        return Err(EvalError::Input(format!("{}: no rows", labels.display())));
    }
    let mut distances: Vec<f64> = rows.iter().map(|r| r.distance).collect();
    distances.sort_by(f64::total_cmp);
    let train_distance = distances[distances.len() / 2];
    let bar = protocol::progress(rows.len() as u64, "loading");
    let mut images = Vec::with_capacity(rows.len());
    for row in &rows {
        let path = dir.join(&row.file);
        let rgb = read_image(&path)?.to_rgb8();
        let (w, h) = rgb.dimensions();
        let mask = match (&row.mask, &row.bbox) {
            (Some(m), _) => read_mask(&dir.join(m), (w, h))?,
            (None, Some(b)) => {
                let mut m = vec![0u8; (w * h) as usize];
                for y in b.y..(b.y + b.height).min(h) {
                    for x in b.x..(b.x + b.width).min(w) {
                        m[(y * w + x) as usize] = 255;
                    }
                }
                m
            }
            (None, None) => vec![255u8; (w * h) as usize],
        };
        images.push((rgb, mask, row));
        bar.inc(1);
    }
    bar.finish_and_clear();
    let labelled: Vec<LabelledView> = images
        .iter()
        .map(|(rgb, mask, row)| LabelledView {
            rgb: rgb.as_raw(),
            mask,
            width: rgb.width(),
            height: rgb.height(),
            theta_deg: row.theta_deg as f32,
            phi_deg: row.phi_deg as f32,
            scale: (train_distance / row.distance) as f32,
        })
        .collect();
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "object".into());
    train_views(&name, train_distance as f32, &labelled, config)
}

/// Reads an image; errors name the file.
pub fn read_image(path: &Path) -> Result<image::DynamicImage, EvalError> {
    image::open(path).map_err(|source| EvalError::Image {
        path: path.to_owned(),
        source,
    })
}

/// Reads an object mask (any image; non-zero luma = object) that must match
/// its image's size; errors name the file.
pub fn read_mask(path: &Path, (w, h): (u32, u32)) -> Result<Vec<u8>, EvalError> {
    let mask = read_image(path)?.to_luma8();
    if mask.dimensions() != (w, h) {
        return Err(EvalError::Input(format!(
            "{}: mask is {}x{} but its image is {w}x{h}",
            path.display(),
            mask.width(),
            mask.height()
        )));
    }
    Ok(mask.into_raw())
}

/// Where default databases are cached: `dir`, else `$XDG_CACHE_HOME/acch`,
/// `~/.cache/acch`, or the temporary directory.
pub fn cache_dir(dir: Option<PathBuf>) -> PathBuf {
    dir.or_else(|| std::env::var_os("XDG_CACHE_HOME").map(|d| PathBuf::from(d).join("acch")))
        .or_else(|| std::env::var_os("HOME").map(|d| PathBuf::from(d).join(".cache/acch")))
        .unwrap_or_else(|| std::env::temp_dir().join("acch"))
}

/// The default database of a built-in object and the file it is cached
/// in: trained on first use with the default recipe and cached, so later
/// runs start at once.
pub fn cached_database(
    object: &Arc<Object>,
    dir: Option<PathBuf>,
) -> Result<(ViewDatabase, PathBuf), EvalError> {
    let dir = cache_dir(dir);
    let path = dir.join(format!(
        "{}-v{}-{}-r{}.acchdb",
        object.name(),
        acch_core::database::FORMAT_VERSION,
        env!("CARGO_PKG_VERSION"),
        TRAINING_REVISION
    ));
    if path.exists() {
        match ViewDatabase::load(&path) {
            Ok(db) => return Ok((db, path)),
            Err(e) => tracing::warn!("retraining: the cached database is unusable: {e}"),
        }
    }
    eprintln!(
        "acch: training the database of '{}' (first use; cached in {})",
        object.name(),
        path.display()
    );
    let confidence = Some((DEFAULT_CONFIDENCE_SCENES, DEFAULT_CONFIDENCE_KIND));
    let db = train_object(
        object,
        &TrainConfig::default(),
        &RenderedTraining::default(),
        confidence,
    )?;
    std::fs::create_dir_all(&dir).map_err(|source| EvalError::Io {
        path: dir.clone(),
        source,
    })?;
    db.save(&path)?;
    Ok((db, path))
}
