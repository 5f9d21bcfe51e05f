//! Fixtures shared by acch's tests and benches, so each trains its models
//! the same way: render a grid of views of an object, build the view
//! database (palette and histograms) and the recognition model from them,
//! as `acch train` does with the default configuration.

use acch_capture::{DEFAULT_DISTANCE, Renderer, ViewSpec};
use acch_core::ViewDatabase;
use acch_pose::train::{LabelledView, TrainConfig, build_database};
use acch_recognition::{RecognitionModel, RecognitionParams};

/// A database and recognition model trained on rendered views.
pub struct Trained {
    /// Palette, histograms and poses of the training views.
    pub db: ViewDatabase,
    /// The recognition model over the database's palette.
    pub model: RecognitionModel,
}

/// Renders `grid`'s views at the training distance with `renderer` (frame
/// 0 of its scene) and trains on them under the default configuration;
/// `object` names the database.
///
/// # Panics
/// If training fails: a fixture's grid and renderer are the caller's
/// constants, so a failure is a bug to show at once.
pub fn train_on_views(object: &str, renderer: &Renderer, grid: &ViewSpec) -> Trained {
    train_on_views_with(object, renderer, grid, &TrainConfig::default())
}

/// [`train_on_views`] under training configuration `config` (a smoothing
/// palette, say).
///
/// # Panics
/// As [`train_on_views`].
pub fn train_on_views_with(
    object: &str,
    renderer: &Renderer,
    grid: &ViewSpec,
    config: &TrainConfig,
) -> Trained {
    let rendered: Vec<_> = grid
        .views(DEFAULT_DISTANCE, 0)
        .iter()
        .map(|v| renderer.render(v, 0))
        .collect();
    let labelled: Vec<LabelledView> = rendered
        .iter()
        .map(|r| {
            let view = (r.truth.theta_deg as f32, r.truth.phi_deg as f32);
            LabelledView::new(
                r.image.as_raw(),
                r.mask.as_raw(),
                r.image.dimensions(),
                view,
                1.0,
            )
        })
        .collect();
    let db = build_database(
        object,
        (DEFAULT_DISTANCE * renderer.config().object.radius_m()) as f32,
        &labelled,
        config,
    )
    .expect("training the view database");
    let model = RecognitionModel::train(&labelled, &db.palette, &RecognitionParams::default())
        .expect("training the recognition model");
    Trained { db, model }
}
