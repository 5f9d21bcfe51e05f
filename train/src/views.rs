//! An object's view histograms, recognition model and shape, trained from
//! rendered views or from photographs (a folder with labels.csv), and the
//! images and masks those are read from.

use crate::TrainingError;
use crate::confidence::ConfidenceScenes;
use crate::scenes::{self, PAPER_GRID};
use acch_capture::{Background, DEFAULT_DISTANCE, Object, Rendered, TextureSet, ViewSpec};
use acch_core::ViewDatabase;
use acch_pose::train::{LabelledView, TrainConfig, build_database};
use acch_recognition::{RecognitionModel, RecognitionParams};
use std::path::Path;
use std::sync::Arc;

/// How to render the training views.
#[derive(Clone, Debug)]
pub struct RenderedTraining {
    /// The views (the paper's grid by default).
    pub views: ViewSpec,
    /// Their background.
    pub background: Background,
    /// Camera distance, object bounding radii (the renderer's unit; the
    /// database stores it in metres, by the object's real radius).
    pub distance: f64,
    /// Seed of the views and the scene.
    pub seed: u64,
    /// How the confidence network's scenes roll, whether the pose stage
    /// searches the roll on them and whether some are imaged under other
    /// light (upright, no search, the training light by default).
    pub scenes: ConfidenceScenes,
    /// The light from this many directions around the vertical, evenly
    /// spaced from the training light's (1: that one only); each view's
    /// histogram is the mean over them, the palette sees them all.
    pub light_directions: usize,
    /// The turns that leave the object looking the same: its shape's
    /// candidates that differ only by one are not rivals.
    pub symmetry: acch_shape::Symmetry,
}

impl Default for RenderedTraining {
    /// The paper's grid on the plain background at the default distance.
    fn default() -> Self {
        RenderedTraining {
            views: PAPER_GRID.parse().expect("the paper grid parses"),
            background: Background::default(),
            distance: DEFAULT_DISTANCE,
            seed: 0,
            scenes: ConfidenceScenes::default(),
            light_directions: 1,
            symmetry: acch_shape::Symmetry::none(),
        }
    }
}

/// Histograms and recognition model from labelled views taken at
/// `distance_m` metres.
pub fn train_views(
    object: &str,
    distance_m: f32,
    views: &[LabelledView<'_>],
    config: &TrainConfig,
) -> Result<ViewDatabase, TrainingError> {
    let mut db = build_database(object, distance_m, views, config)?;
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
) -> Result<ViewDatabase, TrainingError> {
    let renders = render_training(object, training);
    let labelled: Vec<LabelledView> = renders
        .iter()
        .map(|r| scenes::labelled(r, training.distance))
        .collect();
    let distance_m = training.distance * object.radius_m();
    let mut db = train_views(object.name(), distance_m as f32, &labelled, config)?;
    add_shape(&mut db, object, &training.symmetry);
    Ok(db)
}

/// Records `object`'s shape over the default grid ([`acch_shape::default_grid`])
/// and its `symmetry` in `db`.
pub fn add_shape(db: &mut ViewDatabase, object: &Object, symmetry: &acch_shape::Symmetry) {
    let model = acch_shape::ShapeModel::train(object, &acch_shape::default_grid());
    acch_shape::store(db, &model, symmetry);
}

/// The training views of `object` as `training` renders them.
fn render_training(object: &Arc<Object>, training: &RenderedTraining) -> Vec<Rendered> {
    let views = training.views.views(training.distance, training.seed);
    let directions = training.light_directions.max(1);
    let mut renders = Vec::with_capacity(views.len() * directions);
    for k in 0..directions {
        let mut renderer = scenes::renderer(
            object.clone(),
            training.background,
            TextureSet::Training,
            training.seed,
        );
        renderer.set_light_azimuth_deg(360.0 * k as f32 / directions as f32);
        renders.extend(scenes::render_views(
            &renderer,
            &views,
            training.seed,
            "train views",
        ));
    }
    renders
}

/// Gives `db`, trained by `training` before databases recorded their
/// views' colour maps, the maps its training would record now: its
/// training views rendered again and measured by its own palette. Nothing
/// else of it depends on them, so it equals a database trained afresh.
pub(crate) fn add_view_maps(
    db: &mut ViewDatabase,
    object: &Arc<Object>,
    training: &RenderedTraining,
) -> Result<(), TrainingError> {
    let renders = render_training(object, training);
    let labelled: Vec<LabelledView> = renders
        .iter()
        .map(|r| scenes::labelled(r, training.distance))
        .collect();
    let maps = acch_pose::colour_map::measure_view_maps(db, &labelled)?;
    acch_pose::store_view_maps(db, &maps);
    Ok(())
}

/// Trains from `DIR/labels.csv` and the images (and masks) it names. Views
/// without a mask use their bounding box, or the whole image.
pub fn train_from_folder(dir: &Path, config: &TrainConfig) -> Result<ViewDatabase, TrainingError> {
    let labels = dir.join("labels.csv");
    let rows = acch_capture::labels::read_labels(&labels)?;
    if rows.is_empty() {
        return Err(TrainingError::Input(format!(
            "{}: no rows",
            labels.display()
        )));
    }
    let bar = scenes::progress(rows.len() as u64, "loading");
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
    let views: Vec<RealView> = images
        .iter()
        .map(|(rgb, mask, row)| RealView {
            rgb,
            mask,
            view_deg: (row.theta_deg, row.phi_deg),
            roll_deg: row.roll_deg,
            distance_m: row.distance_m,
        })
        .collect();
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "object".into());
    train_real_views(&name, &views, config)
}

/// One photograph of the object to train from.
pub struct RealView<'a> {
    /// The image.
    pub rgb: &'a image::RgbImage,
    /// The object's pixels (non-zero), one byte per pixel.
    pub mask: &'a [u8],
    /// Elevation and azimuth it is seen from, degrees.
    pub view_deg: (f64, f64),
    /// The camera's roll about its optical axis, degrees.
    pub roll_deg: f64,
    /// Distance to the object's centre, metres.
    pub distance_m: f64,
}

/// Histograms and recognition model from photographs of the object, at
/// their median distance (each view scaled to it), searched at runs over
/// the rolls the photographs show ([`crate::cache::roll_search_covering`]):
/// a camera that rolled while they were taken rolls while it runs (LM-O,
/// databases from the even images, with the annotated mask: without the
/// search 17.8-60.6 % of the odd images failed, with it 15.0-47.6 %).
pub fn train_real_views(
    name: &str,
    views: &[RealView<'_>],
    config: &TrainConfig,
) -> Result<ViewDatabase, TrainingError> {
    let mut distances: Vec<f64> = views.iter().map(|v| v.distance_m).collect();
    distances.sort_by(f64::total_cmp);
    let Some(&train_distance) = distances.get(distances.len() / 2) else {
        return Err(TrainingError::Input(format!(
            "{name}: no views to train from"
        )));
    };
    let labelled: Vec<LabelledView> = views
        .iter()
        .map(|v| {
            LabelledView::new(
                v.rgb.as_raw(),
                v.mask,
                v.rgb.dimensions(),
                (v.view_deg.0 as f32, v.view_deg.1 as f32),
                (train_distance / v.distance_m) as f32,
            )
        })
        .collect();
    let mut db = train_views(name, train_distance as f32, &labelled, config)?;
    db.sections
        .insert(acch_core::FROM_PHOTOGRAPHS_SECTION.to_owned(), Vec::new());
    let rolls = crate::cache::roll_search_covering(views.iter().map(|v| v.roll_deg));
    acch_pose::store_roll_search_deg(&mut db, rolls as f32);
    Ok(db)
}

/// Reads an image; errors name the file.
pub fn read_image(path: &Path) -> Result<image::DynamicImage, TrainingError> {
    image::open(path).map_err(|source| TrainingError::Image {
        path: path.to_owned(),
        source,
    })
}

/// Reads an object mask (any image; non-zero luma = object) that must match
/// its image's size; errors name the file.
pub fn read_mask(path: &Path, (w, h): (u32, u32)) -> Result<Vec<u8>, TrainingError> {
    let mask = read_image(path)?.to_luma8();
    if mask.dimensions() != (w, h) {
        return Err(TrainingError::Input(format!(
            "{}: mask is {}x{} but its image is {w}x{h}",
            path.display(),
            mask.width(),
            mask.height()
        )));
    }
    Ok(mask.into_raw())
}
