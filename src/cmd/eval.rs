//! `acch eval`: reproducible accuracy protocols on rendered data, run on
//! the in-process chain of the deployed stages (`acch_eval`).

use super::common::{HistogramArgs, ObjectArgs};
use acch_capture::UpAxis;
use acch_eval::bop::{self, BOP_UNIT_M};
use acch_eval::dataset::{self, DatasetOptions, Segment};
use acch_eval::{multi, robust, roll, sequence, table1, table2};
use acch_pipeline::config::SmoothingChoice;
use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use std::path::PathBuf;
use std::sync::Arc;

/// Evaluation protocols.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum Protocol {
    /// Paper table 1: random poses, ground-truth masks, homogeneous background.
    Table1,
    /// Paper table 2: textured backgrounds and clutter, recognition and
    /// segmentation find the object, confidence network accepts or rejects.
    Table2,
    /// Beyond the paper: camera trajectories, single-frame vs fused
    /// estimates, and active re-view after a rejection.
    Sequence,
    /// Beyond the paper: a camera that rolls. A database trained to search
    /// the roll (--roll-search-deg) on the same poses upright and rolled
    /// (--roll-deg), backgrounds A, B, C and clutter; the whole rotation
    /// judged. --compare adds the default database.
    Roll,
    /// Beyond the paper: the default database under exposure, colour
    /// temperature, brightness, noise, blur, JPEG, occlusion and distance
    /// changes (backgrounds A, B, C; --n poses each); --compare adds the
    /// same scenes without recognition's light search; --plot draws the
    /// failure rate against the level.
    Robust,
    /// Beyond the paper: several known objects at once (--objects), each
    /// scene --in-view of them touching and partly hiding each other among
    /// --distractors, backgrounds A, B, C (--n scenes each); per object
    /// detection recall and precision, IoU and failure rates, with every
    /// object known and with the object's chain alone on the same scenes,
    /// and confusions between objects.
    Multi,
}

/// Arguments of `acch eval`.
#[derive(Args)]
pub struct EvalArgs {
    /// Which protocol to run.
    #[arg(long, value_enum, default_value = "table1")]
    protocol: Protocol,
    #[command(flatten)]
    object: ObjectArgs,
    /// Number of test images (per background for table2; re-view
    /// episodes per background for sequence); default 190 for table1, 50
    /// for table2 and sequence.
    #[arg(long)]
    n: Option<usize>,
    /// sequence: camera trajectories per background.
    #[arg(long, default_value_t = 10)]
    trajectories: usize,
    /// sequence: frames per trajectory.
    #[arg(long, default_value_t = 40)]
    frames: usize,
    /// sequence: frame rate of the trajectories (the arm moves at most about
    /// 10° in θ per 44° of elevation band and 30° in φ per second).
    #[arg(long, default_value_t = 5.0)]
    fps: f64,
    /// sequence: how long the camera's shutter is open, milliseconds (at
    /// most 1000 / --fps): the camera moves along the trajectory meanwhile
    /// and each frame blurs along that motion. 0 = an instant.
    #[arg(long, default_value_t = 0.0)]
    shutter_ms: f64,
    /// sequence: lowest elevation of the trajectories, degrees. The default
    /// 20 takes the camera below the database's 45°, as a real arm's does
    /// (and as the confidence network's training scenes); 45.5 keeps it in
    /// the database's range (the earlier, easier protocol).
    #[arg(long, default_value_t = 20.0)]
    theta_min: f64,
    /// sequence: highest elevation of the trajectories, degrees (45.5 and
    /// 89.5 give the earlier in-range protocol).
    #[arg(long, default_value_t = 90.0)]
    theta_max: f64,
    /// sequence: moves allowed per re-view episode.
    #[arg(long, default_value_t = 8)]
    max_moves: usize,
    /// sequence: confidence-training scenes per background (fewer train
    /// faster and worse).
    #[arg(long, default_value_t = acch_train::confidence::DEFAULT_CONFIDENCE_SCENES)]
    confidence_scenes: usize,
    /// Seed of the scene and of the test poses (training views use seed 0).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also evaluate variants: CCH, DCCH, local vs annulus, winner takes all
    /// vs refined, scale from the ROI, RGB palette.
    #[arg(long)]
    compare: bool,
    /// table1, roll: roll the test views' camera uniformly in ±DEG about
    /// its optical axis (default 0 for table1, 45 for roll).
    #[arg(long, value_name = "DEG")]
    roll_deg: Option<f64>,
    /// The largest roll the pose stage searches, degrees: table1 (default
    /// 0: none); roll: the search the database is trained with (default
    /// 45); multi: the search the databases are trained for (default 45:
    /// objects off the optical axis are seen rolled; 0: the default
    /// databases);
    /// --bop, --labels (default: what the database was trained with).
    #[arg(long, value_name = "DEG")]
    roll_search_deg: Option<f64>,
    /// --bop, --labels: lights (exposures and colour temperatures)
    /// recognition tries on an image whose object is weak or lost under
    /// the training light; 0 (the default): none; 20: all, the light then
    /// chosen again by how much of the region a view explains. It finds
    /// textured objects under other light, but on flat-coloured ones
    /// makes wrong estimates that are accepted (docs/accuracy.md).
    #[arg(long, value_name = "N", default_value_t = 0)]
    light_search: usize,
    /// Write the results as JSON.
    #[arg(long, value_name = "FILE")]
    json: Option<PathBuf>,
    /// table2: the table textures of the test scenes: held-out (none of the
    /// confidence network's training scenes shows them) or training.
    #[arg(long, value_name = "SET", default_value = "held-out")]
    textures: acch_capture::TextureSet,
    /// robust: the perturbation families to measure, comma-separated
    /// (exposure, brightness, colour_temperature, noise, blur,
    /// motion_blur, sensor_noise, jpeg, occlusion, distance,
    /// light_direction); default: all.
    #[arg(long, value_name = "NAMES", value_delimiter = ',')]
    families: Vec<String>,
    /// robust: measure over several objects and pool the rows; multi: the
    /// known objects. A
    /// comma-separated list of built-in names, generated-N, random:N (N
    /// generated objects, a population drawn from --seed, so the
    /// development and evaluation seeds never share an object) and mesh
    /// files, e.g. random:50,fruitbox,can,../duck.obj. Each object's
    /// default database is trained on first use and cached.
    #[arg(long, value_name = "LIST", conflicts_with_all = ["object", "mesh"])]
    objects: Option<String>,
    /// multi: known objects in each scene (default: 3, or all if fewer
    /// are known).
    #[arg(long, value_name = "N")]
    in_view: Option<usize>,
    /// multi: unknown objects standing around the known ones.
    #[arg(long, value_name = "N", default_value_t = 2)]
    distractors: usize,
    /// multi: one light fixed in the world, so an object turned on the
    /// table is lit from another side than its training views (default:
    /// each object lit as in training).
    #[arg(long)]
    world_light: bool,
    /// robust, multi: the databases whose confidence network also saw imaged
    /// scenes and may read the absolute match value (`acch train
    /// --confidence-imaging`), trained on first use and cached apart from
    /// the default ones.
    #[arg(long)]
    confidence_imaging: bool,
    /// table2, robust, multi: the databases trained with their views lit
    /// from K directions around the vertical and half the confidence scenes
    /// from a turned one (`acch train --light-directions K`), trained on
    /// first use and cached apart from the default ones (1: the default).
    #[arg(long, value_name = "K", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=64))]
    light_directions: u32,
    /// robust: plot the failure rate against each family's level (PNG).
    #[arg(long, value_name = "FILE.png")]
    plot: Option<PathBuf>,
    /// table2: write the confidence reliability diagram (PNG).
    #[arg(long, value_name = "FILE.png")]
    reliability: Option<PathBuf>,
    /// table1, robust, multi: write every test image's truth, estimate and
    /// errors as CSV (table1: the first variant; robust: every family,
    /// level and object).
    #[arg(long, value_name = "FILE.csv")]
    errors: Option<PathBuf>,
    #[command(flatten)]
    histogram: HistogramArgs,
    /// Evaluate on a BOP dataset instead of rendered views: every annotated
    /// instance of --object ID (a number: BOP's obj_id) in --split. The
    /// database is --db, or that of the model DIR/models/obj_ID.ply
    /// (millimetres, --mesh-up +z unless given), trained on first use and
    /// cached.
    #[arg(long, value_name = "DIR", conflicts_with = "labels")]
    bop: Option<PathBuf>,
    /// BOP: the split to read (DIR/SPLIT/SCENE/...).
    #[arg(long, value_name = "NAME", default_value = "test", requires = "bop")]
    split: String,
    /// Evaluate on a folder of labelled images instead (labels.csv as
    /// `acch render` writes it, with masks).
    #[arg(long, value_name = "DIR")]
    labels: Option<PathBuf>,
    /// --bop/--labels: where the object comes from: mask (the annotated
    /// visible part, table 1's figures) or auto (recognition and
    /// segmentation, table 2's).
    #[arg(long, value_enum, default_value = "mask")]
    segment: SegmentArg,
    /// --bop/--labels: the view database (`acch train`); default: the
    /// object's, trained on first use and cached.
    #[arg(long, value_name = "FILE.acchdb")]
    db: Option<PathBuf>,
    /// --bop: the object's symmetry, when the dataset's models_info.json
    /// lists none: AXIS:N (every 1/N turn about the model's x, y or z
    /// axis through its bounding-box centre looks the same; z:2 for a half
    /// turn) or AXIS:inf. An estimate right for any of the poses it makes
    /// of the annotated one is right, as BOP's metrics score it.
    #[arg(long, value_name = "SPEC", requires = "bop")]
    symmetry: Option<String>,
    /// --bop: also write every estimate with a 6-DOF pose, accepted or
    /// not, in the BOP challenge's results format
    /// (scene_id,im_id,obj_id,score,R,t,time; R row-major model to camera,
    /// t in mm). The score is the one acch accepts by: accepted ones score
    /// at least 1.
    #[arg(long, value_name = "FILE.csv", requires = "bop")]
    bop_results: Option<PathBuf>,
    /// --bop: train the database from the dataset's own photographs
    /// instead of the model's renders (the paper's route: real views, the
    /// histograms from their annotated masks; the model still gives the
    /// shape): those of the images with an even (odd) id, and evaluate on
    /// the others.
    #[arg(
        long,
        value_enum,
        value_name = "PARITY",
        requires = "bop",
        conflicts_with = "db"
    )]
    train_on: Option<ParityArg>,
}

/// `--train-on`: which images train the database.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum ParityArg {
    /// Images with an even id.
    Even,
    /// Images with an odd id.
    Odd,
}

/// Where `acch eval --bop/--labels` takes the object from.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum SegmentArg {
    /// The annotated mask.
    Mask,
    /// Recognition and segmentation.
    Auto,
}

/// Runs `acch eval`.
pub fn run(args: EvalArgs) -> Result<()> {
    let writes_errors = matches!(
        args.protocol,
        Protocol::Table1 | Protocol::Robust | Protocol::Multi
    );
    if args.errors.is_some() && (!writes_errors || args.bop.is_some() || args.labels.is_some()) {
        bail!("--errors is written by --protocol table1, robust and multi only");
    }
    if args.bop.is_some() || args.labels.is_some() {
        return run_dataset(args);
    }
    if let Some(spec) = &args.objects {
        return run_population(&args, spec);
    }
    if args.histogram.smoothing == SmoothingChoice::ByFrame
        && !matches!(args.protocol, Protocol::Robust)
    {
        bail!("--smoothing auto (the databases chosen per frame) is measured by --protocol robust");
    }
    let object = args.object.load()?;
    let config = args.histogram.train_config()?;
    match args.protocol {
        Protocol::Table1 => {
            let options = table1::Table1Options {
                n: args.n.unwrap_or(190),
                seed: args.seed,
                compare: args.compare,
                roll_deg: args.roll_deg.unwrap_or(0.0),
                roll_search_deg: args.roll_search_deg.unwrap_or(0.0),
            };
            let report = table1::table1(object, &options, &config)?;
            report.print();
            if let Some(path) = &args.json {
                report.write_json(path)?;
            }
            if let Some(path) = &args.errors {
                report.write_errors(path)?;
            }
        }
        Protocol::Table2 => {
            let options = table2::Table2Options {
                n: args.n.unwrap_or(50),
                seed: args.seed,
                textures: args.textures,
                light_directions: args.light_directions as usize,
            };
            let report = table2::table2(object, &options, &config)?;
            report.print();
            if let Some(path) = &args.json {
                report.write_json(path)?;
            }
            if let Some(path) = &args.reliability {
                report.write_reliability(path)?;
            }
        }
        Protocol::Sequence => {
            let options = sequence::SequenceOptions {
                trajectories: args.trajectories,
                frames: args.frames,
                fps: args.fps,
                shutter_s: args.shutter_ms / 1000.0,
                theta_band: (args.theta_min, args.theta_max),
                episodes: args.n.unwrap_or(50),
                max_moves: args.max_moves,
                seed: args.seed,
                confidence_scenes: args.confidence_scenes,
            };
            let report = sequence::sequence(object, &options, &config)?;
            report.print();
            if let Some(path) = &args.json {
                report.write_json(path)?;
            }
        }
        Protocol::Roll => {
            let options = roll::RollOptions {
                n: args.n.unwrap_or(50),
                seed: args.seed,
                roll_deg: args.roll_deg.unwrap_or(45.0),
                search_deg: args.roll_search_deg.unwrap_or(45.0),
                confidence_scenes: args.confidence_scenes,
                compare: args.compare,
            };
            let report = roll::roll(object, &options, &config)?;
            report.print();
            if let Some(path) = &args.json {
                report.write_json(path)?;
            }
        }
        Protocol::Multi => bail!(
            "--protocol multi needs the known objects: --objects LIST, e.g. fruitbox,can,random:2"
        ),
        Protocol::Robust => {
            let options = robust_options(&args, 20);
            let (db, smoothed) = robust_databases(&args, &object)?;
            let report = robust::robust(object, (&db, smoothed.as_ref()), &options)?;
            report.print();
            if let Some(path) = &args.json {
                report.write_json(path)?;
            }
            if let Some(path) = &args.errors {
                report.write_errors(path)?;
            }
            if let Some(path) = &args.plot {
                report.write_plot(path)?;
            }
        }
    }
    Ok(())
}

/// The robust protocol's options, `default_n` poses per background
/// unless `--n` says otherwise.
fn robust_options(args: &EvalArgs, default_n: usize) -> robust::RobustOptions {
    robust::RobustOptions {
        n: args.n.unwrap_or(default_n),
        seed: args.seed,
        compare: args.compare,
        families: args.families.clone(),
        database: if args.confidence_imaging {
            "imaging-aware"
        } else if args.light_directions > 1 {
            "light-tolerant"
        } else if args.histogram.smoothing == SmoothingChoice::ByFrame {
            "chosen per frame"
        } else if args.histogram.smoothing.fixed() != acch_core::Smoothing::Off {
            "smoothing"
        } else {
            "default"
        },
    }
}

/// The databases the robust protocol measures for `object`: the default,
/// the imaging-aware, the smoothing or the light-tolerant one (cached)
/// and, with `--smoothing auto`, the smoothed one with the confidence for
/// a worse camera, chosen per frame.
fn robust_databases(
    args: &EvalArgs,
    object: &Arc<acch_capture::Object>,
) -> Result<robust::Databases, acch_eval::EvalError> {
    let recipe = acch_train::cache::Recipe {
        imaging: args.confidence_imaging,
        light_directions: args.light_directions as usize,
        smoothing: args.histogram.smoothing.fixed(),
        ..Default::default()
    };
    let (db, _) = acch_train::cache::cached_recipe_database(object, None, recipe)?;
    if args.histogram.smoothing != SmoothingChoice::ByFrame {
        return Ok((db, None));
    }
    let (smoothed, _) =
        acch_train::cache::cached_recipe_database(object, None, recipe.smoothed_set())?;
    Ok((db, Some(smoothed)))
}

/// `acch eval --protocol robust --objects LIST`.
fn run_population(args: &EvalArgs, spec: &str) -> Result<()> {
    let up = args.object.mesh_up.unwrap_or_default();
    let objects = super::common::load_objects(spec, args.seed, up)?;
    match args.protocol {
        Protocol::Robust => {}
        Protocol::Multi => return run_multi(args, &objects),
        _ => bail!("--objects is measured by --protocol robust and multi only"),
    }
    let options = robust_options(args, 4);
    let database = |o: &Arc<acch_capture::Object>| robust_databases(args, o);
    let report = robust::robust_population(&objects, &database, &options)?;
    report.print();
    if let Some(path) = &args.json {
        report.write_json(path)?;
    }
    if let Some(path) = &args.errors {
        report.write_errors(path)?;
    }
    if let Some(path) = &args.plot {
        report.write_plot(path)?;
    }
    Ok(())
}

/// `acch eval --protocol multi --objects LIST`.
fn run_multi(args: &EvalArgs, objects: &[Arc<acch_capture::Object>]) -> Result<()> {
    let options = multi::MultiOptions {
        n: args.n.unwrap_or(50),
        seed: args.seed,
        in_view: args.in_view.unwrap_or(objects.len().min(3)),
        distractors: args.distractors,
        light: if args.world_light {
            acch_capture::SceneLight::World
        } else {
            acch_capture::SceneLight::AsTrained
        },
    };
    // Refused before any database is trained.
    options.check(objects.len())?;
    if args.histogram.smoothing == SmoothingChoice::ByFrame {
        bail!(
            "--smoothing auto is for one object: several objects share a palette of their sharp databases"
        );
    }
    let databases = objects
        .iter()
        .map(|o| {
            let recipe = acch_train::cache::Recipe {
                roll_search_deg: args
                    .roll_search_deg
                    .unwrap_or(multi::OFF_AXIS_ROLL_SEARCH_DEG),
                light_directions: args.light_directions as usize,
                smoothing: args.histogram.smoothing.fixed(),
                imaging: args.confidence_imaging,
                ..Default::default()
            };
            acch_train::cache::cached_recipe_database(o, None, recipe).map(|(db, _)| db)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let report = multi::multi(objects, &databases, &options)?;
    report.print();
    if let Some(path) = &args.json {
        report.write_json(path)?;
    }
    if let Some(path) = &args.errors {
        report.write_errors(path)?;
    }
    Ok(())
}

/// `acch eval --bop DIR` or `--labels DIR`.
fn run_dataset(args: EvalArgs) -> Result<()> {
    let options = DatasetOptions {
        segment: match args.segment {
            SegmentArg::Mask => Segment::Mask,
            SegmentArg::Auto => Segment::Auto,
        },
        roll_search_deg: args.roll_search_deg.map(|d| d as f32),
        light_search: args.light_search,
    };
    let mut symmetry = None;
    let mut bop_model = None;
    let (images, source, object) = if let Some(dir) = &args.bop {
        let id_text = args.object.object.as_deref().ok_or_else(|| {
            anyhow::anyhow!("--bop needs --object ID, the BOP obj_id of the object to evaluate")
        })?;
        let obj_id: u32 = id_text.parse().with_context(|| {
            format!("--object {id_text}: with --bop the object is BOP's numeric obj_id")
        })?;
        let (info, info_derived) = bop::model_info(dir, obj_id)?;
        let up = args.object.mesh_up.unwrap_or(UpAxis::PosZ);
        let path = bop::find_model(dir, obj_id);
        let model = acch_capture::Object::load_mesh(&path, up)
            .with_context(|| format!("loading the model {}", path.display()))?
            .with_mesh_unit_m(BOP_UNIT_M)?;
        let declared = match &args.symmetry {
            Some(spec) => acch_shape::Symmetry::parse(spec)?,
            None => bop::symmetry_of_model(&info, &model),
        };
        let symmetry = symmetry.insert(declared);
        let cache = acch_train::cache::cache_dir(None);
        let (images, mut derived) =
            dataset::from_bop(dir, &args.split, obj_id, &model, symmetry, &cache)?;
        if info_derived {
            derived.insert(
                0,
                format!(
                    "object {obj_id}'s diameter and bounding box from its model (no models_info.json){}",
                    if symmetry.is_none() {
                        "; no symmetry (none declared with --symmetry)"
                    } else {
                        ""
                    }
                ),
            );
        }
        for line in &derived {
            eprintln!("derived: {line}");
        }
        let model = Arc::new(model);
        bop_model = Some((obj_id, Arc::clone(&model)));
        // Without --db, the database of the dataset's model.
        let object = match &args.db {
            Some(_) => None,
            None => Some(model),
        };
        let source = format!("bop {} {}", dir.display(), args.split);
        (images, source, object)
    } else {
        let dir = args
            .labels
            .as_ref()
            .expect("run_dataset is called with one of them");
        let object = match &args.db {
            Some(_) => None,
            None => Some(args.object.load()?),
        };
        (
            dataset::from_labels(dir)?,
            format!("labels {}", dir.display()),
            object,
        )
    };
    // --train-on: the database from some of the photographs, the
    // evaluation on the rest.
    let (images, trained) = match (args.train_on, &object) {
        (Some(parity), Some(object)) => {
            let parity = match parity {
                ParityArg::Even => dataset::ImageParity::Even,
                ParityArg::Odd => dataset::ImageParity::Odd,
            };
            let (train, test) = parity.split(images);
            eprintln!(
                "trained from {} instances' photographs ({parity:?} image ids), evaluated on the other {}",
                train.len(),
                test.len()
            );
            let config = args.histogram.train_config()?;
            let symmetry = symmetry.clone().unwrap_or_else(acch_shape::Symmetry::none);
            let db = dataset::train_on_images(&train, object, &symmetry, &config)?;
            if args.roll_search_deg.is_none() {
                eprintln!(
                    "derived: the roll searched within ±{}°: the roll of 95 % of the training photographs",
                    acch_pose::trained_roll_search_deg(&db)
                );
            }
            (test, Some(db))
        }
        _ => (images, None),
    };
    let mut db = match (trained, &args.db, &object) {
        (Some(db), _, _) => db,
        (None, Some(path), _) => acch_core::ViewDatabase::load(path)?,
        (None, None, Some(object)) if args.bop.is_some() => {
            // The dataset's camera: its range of views and distance.
            let recipe = dataset::dataset_recipe(&images, object);
            eprintln!(
                "derived: training views from {}° to 90° of elevation at {:.2} m, the roll searched within ±{}°: the dataset's lowest view, median distance and the roll of 95 % of its instances",
                recipe.lowest_theta_deg.unwrap_or(45),
                recipe
                    .distance_radii
                    .unwrap_or(acch_capture::DEFAULT_DISTANCE)
                    * object.radius_m(),
                recipe.roll_search_deg
            );
            acch_train::cache::cached_recipe_database(object, None, recipe)?.0
        }
        (None, None, Some(object)) => acch_train::cache::cached_database(object, None)?.0,
        (None, None, None) => bail!("no database: name one with --db"),
    };
    // The dataset's (or the declared) symmetry of the object.
    if let (Some(symmetry), Ok(Some((model, _)))) = (&symmetry, acch_shape::stored(&db)) {
        acch_shape::store(&mut db, &model, symmetry);
    }
    let report = dataset::evaluate(&db, &images, &options, &source)?;
    report.print();
    if let Some(path) = &args.json {
        report.write_json(path)?;
    }
    if let (Some(path), Some((obj_id, model))) = (&args.bop_results, &bop_model) {
        report.write_bop_results(path, *obj_id, model)?;
        eprintln!("wrote the BOP results to {}", path.display());
    }
    Ok(())
}
