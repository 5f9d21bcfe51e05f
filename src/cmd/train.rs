//! `acch train`: build a view database from a rendered object or from a
//! folder of labelled images.

use super::common::{HistogramArgs, ObjectArgs};
use acch_capture::{Background, DEFAULT_DISTANCE, ViewSpec};
use acch_train::confidence::{ConfidenceScenes, DEFAULT_CONFIDENCE_SCENES, train_object};
use acch_train::views::{RenderedTraining, train_from_folder};
use anyhow::{Result, bail};
use clap::Args;
use std::path::PathBuf;

/// Arguments of `acch train`.
#[derive(Args)]
pub struct TrainArgs {
    #[command(flatten)]
    object: ObjectArgs,
    /// Train from real images instead: a folder with labels.csv (file,
    /// theta_deg, phi_deg, distance_m, bbox, mask) as `acch render` writes
    /// it; distances in metres make the poses metric.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["object", "mesh"])]
    images: Option<PathBuf>,
    /// Training views: grid:THETAS:PHI_STEP or random:N.
    #[arg(long, default_value = "grid:45,50,60,70,80,90:10")]
    views: ViewSpec,
    /// Background of the rendered training views.
    #[arg(long, default_value = "plain")]
    background: Background,
    /// Camera distance of rendered views, in object bounding radii (the
    /// database stores it in metres, by the object's real radius).
    #[arg(long, default_value_t = DEFAULT_DISTANCE)]
    distance: f64,
    /// Seed of the rendered views.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    #[command(flatten)]
    histogram: HistogramArgs,
    /// Confidence network: random-pose scenes rendered per background (plain,
    /// A, B, C, clutter, clutter-similar) to train it on; 0 leaves it out.
    #[arg(long, default_value_t = DEFAULT_CONFIDENCE_SCENES)]
    confidence_scenes: usize,
    /// For a camera that rolls: the pose stage searches the roll within
    /// ±DEG, the confidence network is trained on the responses of that
    /// search over scenes rolled as far (every other one; see
    /// --confidence-roll-deg), and the database records the search, so
    /// `acch run`, `estimate` and `eval` use it unless told otherwise
    /// (docs/accuracy.md, "The camera rolls"). 0 (the default): no search,
    /// image up is the training views' up.
    #[arg(long, value_name = "DEG", default_value_t = 0.0)]
    roll_search_deg: f64,
    /// Roll the camera of every other confidence-training scene uniformly
    /// within ±DEG about its optical axis, labelling its estimate by the
    /// whole rotation; default: --roll-search-deg. Without the search
    /// (--roll-search-deg 0) the network learns to reject seeds turned by
    /// the roll, at a cost: measured, wrong rotations among the accepted
    /// of rolled views fell from 53 % to 12 % (fruitbox), upright
    /// acceptance from about 100 % to 54-92 % (docs/accuracy.md).
    #[arg(long, value_name = "DEG")]
    confidence_roll_deg: Option<f64>,
    /// Image every other confidence-training scene under other light or a
    /// worse camera (one of exposure 0.4-2.5x, 3000-7500 K, byte
    /// brightness, noise, blur, JPEG, an occluding bar), recognise them
    /// with the light search, and add the grounded input (the features and
    /// the absolute match value) to the candidates: a network that rejects
    /// weak matches instead of accepting them at 0.999 (docs/accuracy.md,
    /// "A confidence that knows when it is out of its depth").
    #[arg(long)]
    confidence_imaging: bool,
    /// Light the training views from this many directions around the
    /// vertical, evenly spaced from the training light's, each view's
    /// histogram the mean over them, and half the confidence scenes from a
    /// turned direction: for a room whose light does not come from where
    /// training's did (docs/accuracy.md, "Light from another side").
    #[arg(long, value_name = "K", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
    light_directions: u32,
    /// The object's symmetry: AXIS:N when every 1/N turn about the
    /// object's x, y or z axis (after --mesh-up) through its centre looks
    /// the same (z:2: a half turn about its up axis), AXIS:inf for any
    /// turn, none (the default). Two poses one turn apart are then one
    /// pose: never each other's rival.
    #[arg(long, value_name = "SPEC", default_value = "none", value_parser = parse_symmetry)]
    symmetry: acch_shape::Symmetry,
    /// Confidence network input: the four response features, the whole
    /// response, or the features and the best match value (grounded).
    #[arg(long, value_enum, default_value = "auto")]
    confidence_input: ConfidenceInput,
    /// Confidence below which an estimate is rejected; stored in the
    /// database (`acch estimate --threshold` overrides it per call).
    #[arg(long, default_value_t = acch_confidence::DEFAULT_THRESHOLD)]
    confidence_threshold: f32,
    /// Output database file.
    #[arg(long, value_name = "FILE.acchdb")]
    out: PathBuf,
}

/// What the confidence network reads.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum ConfidenceInput {
    /// Every candidate trained (features and response; with
    /// --confidence-imaging grounded too); the one with the higher ROC AUC
    /// on validation scenes (never a training or a test scene) kept.
    Auto,
    /// R_phi, D_phi, R_theta, D_theta (paper, section 4).
    Features,
    /// The whole match-value response, normalised by its maximum.
    Response,
    /// The four features and the best match value, absolute.
    Grounded,
}

impl From<ConfidenceInput> for acch_train::confidence::ConfidenceInput {
    fn from(c: ConfidenceInput) -> Self {
        match c {
            ConfidenceInput::Auto => acch_train::confidence::ConfidenceInput::Auto,
            ConfidenceInput::Features => {
                acch_train::confidence::ConfidenceInput::Only(acch_confidence::Kind::Features)
            }
            ConfidenceInput::Response => {
                acch_train::confidence::ConfidenceInput::Only(acch_confidence::Kind::Response)
            }
            ConfidenceInput::Grounded => {
                acch_train::confidence::ConfidenceInput::Only(acch_confidence::Kind::Grounded)
            }
        }
    }
}

/// Runs `acch train`.
pub fn run(args: TrainArgs) -> Result<()> {
    if args.histogram.smoothing == acch_pipeline::config::SmoothingChoice::ByFrame {
        bail!(
            "--smoothing auto chooses between two databases per frame (acch run, acch eval \
             --protocol robust): train each, --smoothing off and --smoothing binomial \
             --confidence-imaging"
        );
    }
    let config = args.histogram.train_config()?;
    // Checked before the long training, not after it.
    let confidence_roll_deg = args.confidence_roll_deg.unwrap_or(args.roll_search_deg);
    for (name, deg) in [
        ("--roll-search-deg", args.roll_search_deg),
        ("--confidence-roll-deg", confidence_roll_deg),
    ] {
        if !(deg.is_finite() && (0.0..=180.0).contains(&deg)) {
            bail!("{name} {deg} must be a finite number of degrees in [0, 180]");
        }
    }
    if args.images.is_some() && args.confidence_imaging {
        bail!(
            "--confidence-imaging trains the confidence network on rendered scenes; with --images there is none"
        );
    }
    if args.images.is_some() && args.roll_search_deg > 0.0 {
        bail!(
            "--roll-search-deg trains the confidence network on rendered scenes; with --images there is none (search the roll at run time with roll_search_deg in the config)"
        );
    }
    if !(0.0..=1.0).contains(&args.confidence_threshold) {
        bail!(
            "--confidence-threshold {} must lie in [0, 1]",
            args.confidence_threshold
        );
    }
    let start = std::time::Instant::now();
    let db = match &args.images {
        Some(dir) => {
            let db = train_from_folder(dir, &config)?;
            println!(
                "no confidence network (labelled images give no failures to learn from): run it with `acch run --unrated`"
            );
            db
        }
        None => {
            let object = args.object.load()?;
            let training = RenderedTraining {
                views: args.views.clone(),
                background: args.background,
                distance: args.distance,
                seed: args.seed,
                scenes: ConfidenceScenes {
                    roll_deg: confidence_roll_deg,
                    search_deg: args.roll_search_deg,
                    imaging: args.confidence_imaging,
                    light_turned: args.light_directions > 1,
                },
                light_directions: args.light_directions as usize,
                symmetry: args.symmetry.clone(),
            };
            let confidence = Some((args.confidence_scenes, args.confidence_input.into()));
            let (mut db, choice) = train_object(&object, &config, &training, confidence)?;
            if let Some(c) = choice {
                println!("{c}");
            }
            if args.confidence_scenes > 0 {
                let mut network = acch_confidence::Model::load(&db)?;
                network.set_threshold(args.confidence_threshold)?;
                network.store(&mut db);
            }
            db
        }
    };
    db.save(&args.out)?;
    println!(
        "trained {} views of '{}' ({} colours, {} bins of {}) in {:.1} s -> {}",
        db.views().len(),
        db.object,
        db.palette.len(),
        db.params.len(),
        db.params.kind,
        start.elapsed().as_secs_f64(),
        args.out.display()
    );
    let search = acch_pose::trained_roll_search_deg(&db);
    if search > 0.0 {
        println!(
            "roll search ±{search}° recorded: acch run, estimate and eval search the roll with this database"
        );
    } else if args.images.is_some() {
        println!("no roll search recorded: the photographs are upright");
    }
    Ok(())
}

/// `--symmetry`.
fn parse_symmetry(spec: &str) -> Result<acch_shape::Symmetry, String> {
    acch_shape::Symmetry::parse(spec).map_err(|e| e.to_string())
}
