//! Beyond the paper: imaging as a robot's camera does it. The deployed
//! chain (recognition with its light search, segmentation, pose,
//! confidence) on random poses over backgrounds A, B and C, each scene
//! rendered clean and under one perturbation per family and level: the
//! light's exposure and colour temperature, a byte brightness change,
//! sensor noise, blur, JPEG, an occluding bar and the camera's distance.
//! The database is the object's default one, trained on clean views
//! under the training light. With `compare`, the same scenes without the
//! light search beside it.

use crate::protocol::{self, fails};
use crate::{EvalError, write_json};
use acch_capture::{
    Background, DEFAULT_DISTANCE, Object, Rendered, Renderer, SceneConfig, TextureSet, ViewSpec,
};
use acch_core::ViewDatabase;
use acch_pipeline::Hop;
use acch_pipeline::stages::SINGLE_IMAGE_LIGHT_SEARCH;
use acch_pose::phi_error;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// One perturbation family and its levels.
pub struct Family {
    /// Its name in the rows.
    pub name: &'static str,
    /// What the level means.
    pub unit: &'static str,
    /// The levels measured.
    pub levels: &'static [f64],
}

/// The families and levels measured; the clean scene is level "clean" of
/// every family's row set.
pub const FAMILIES: [Family; 12] = [
    Family {
        name: "exposure",
        unit: "x linear light",
        levels: &[0.5, 0.6, 0.8, 1.25, 1.5, 2.0],
    },
    Family {
        name: "brightness",
        unit: "x sRGB bytes",
        levels: &[0.6, 0.8, 1.25, 1.5],
    },
    Family {
        name: "colour_temperature",
        unit: "K (training light 5000 K)",
        levels: &[3000.0, 3500.0, 4250.0, 5750.0, 6500.0, 7500.0],
    },
    Family {
        name: "noise",
        unit: "sigma, grey levels",
        levels: &[2.0, 4.0, 6.0],
    },
    Family {
        name: "blur",
        unit: "sigma, px",
        levels: &[0.5, 1.0, 2.0],
    },
    Family {
        name: "motion_blur",
        unit: "px streak at 30 degrees",
        levels: &[2.0, 4.0, 8.0],
    },
    Family {
        name: "sensor_noise",
        unit: "electrons at white (full well / gain), read noise 3 e",
        levels: &[4000.0, 1000.0, 400.0],
    },
    Family {
        name: "jpeg",
        unit: "quality",
        levels: &[90.0, 75.0, 60.0],
    },
    Family {
        name: "occlusion",
        unit: "share of the width",
        levels: &[0.1, 0.2, 0.3],
    },
    Family {
        name: "occluding_object",
        unit: "share of the width, another object in front",
        levels: &[0.1, 0.2, 0.3],
    },
    Family {
        name: "distance",
        unit: "x training distance",
        levels: &[0.7, 0.85, 1.25, 1.5],
    },
    Family {
        name: "light_direction",
        unit: "degrees the light is turned about the vertical",
        levels: &[20.0, 45.0, 70.0, 90.0, 110.0, 135.0, 160.0, 180.0],
    },
];

/// The backgrounds every object is seen on.
pub const BACKGROUNDS: [&str; 3] = ["A", "B", "C"];

/// Options of the robust protocol.
#[derive(Clone, Debug)]
pub struct RobustOptions {
    /// Random test poses per background.
    pub n: usize,
    /// Seed of the poses and the scenes.
    pub seed: u64,
    /// Also run without the light search.
    pub compare: bool,
    /// The families to measure (by [`Family::name`]); empty: all.
    pub families: Vec<String>,
    /// Which database is measured, for the report: "default" or
    /// "imaging-aware".
    pub database: &'static str,
}

/// An object's sharp database and, with `--smoothing auto`, its smoothed
/// one, chosen per frame.
pub type Databases = (ViewDatabase, Option<ViewDatabase>);

/// One row: a family at a level, over every background.
#[derive(Clone, Debug, Serialize)]
pub struct RobustRow {
    /// Perturbation family ("clean" for none).
    pub family: String,
    /// Its level (0 for clean).
    pub level: f64,
    /// Whether recognition searched the light.
    pub light_search: bool,
    /// Test images.
    pub n: usize,
    /// Share in which the object was not found.
    pub not_found_rate: f64,
    /// Share of failures before the confidence network: the paper's rule,
    /// or not found.
    pub failure_rate: f64,
    /// Share accepted by the confidence network.
    pub accepted_rate: f64,
    /// Failures among the accepted.
    pub acc_failure_rate: f64,
    /// Mean |Δφ| over the estimates, degrees.
    pub mean_phi_err_deg: f64,
    /// Mean |Δθ| over the estimates, degrees.
    pub mean_theta_err_deg: f64,
    /// Every image's outcome, in the order of the scenes (background by
    /// background), for `--errors`; not in the JSON, and empty in a pooled
    /// row (its objects' reports hold them).
    #[serde(skip)]
    pub images: Vec<ImageOutcome>,
}

/// What became of one image.
#[derive(Clone, Copy, Debug)]
pub struct ImageOutcome {
    /// True (θ, φ), degrees.
    pub truth: (f32, f32),
    /// The estimate (θ, φ), degrees; None: not found.
    pub estimate: Option<(f32, f32)>,
    /// Wrong by the paper's rule, or not found.
    pub failed: bool,
    /// Accepted by the confidence network.
    pub accepted: bool,
    /// The best view's match value; None: not found.
    pub match_value: Option<f32>,
    /// The confidence network's output; None: not rated.
    pub confidence: Option<f32>,
    /// The best match beyond 20° of the estimate's azimuth or 10° of its
    /// elevation over the best
    /// ([`acch_confidence::rival_ratio`]); None: not found.
    pub rival: Option<f32>,
    /// The span in azimuth of the views about the estimate that match
    /// nearly as well ([`acch_confidence::phi_plateau_deg`]); None: not
    /// rated.
    pub phi_plateau_deg: Option<f32>,
    /// How much more of the region's coloured area a view 20-60° away in
    /// azimuth holds in place than the estimate's
    /// ([`acch_pose::PoseEstimator::map_rival`]); None: not rated, or
    /// nothing weighed.
    pub map_rival: Option<f32>,
    /// How the training view nearest the truth, as a query, rates the view
    /// the estimate chose ([`acch_pose::PoseEstimator::respond_to_view`],
    /// sharp database): 1 for the same view; at or above
    /// [`acch_confidence::MAX_RIVAL_RATIO`] the database itself cannot
    /// tell the truth from the estimate. None: not found.
    pub look_alike: Option<f32>,
    /// The detection's score over its threshold; None: not found.
    pub score_margin: Option<f32>,
    /// The frame's measured noise, JPEG blocking and sharpness.
    pub quality: acch_core::FrameQuality,
    /// The database set the chain ran the frame through (`--smoothing
    /// auto` chooses; otherwise sharp).
    pub set: acch_pipeline::wire::DatabaseSet,
    /// Sharpness over the object's window as the chain measured it to
    /// choose (`--smoothing auto`; 0: not measured).
    pub object_sharpness: f32,
}

/// The robust protocol's report.
#[derive(Serialize, Debug)]
pub struct RobustReport {
    /// "robust".
    pub protocol: &'static str,
    /// The object.
    pub object: String,
    /// Test poses per background.
    pub n: usize,
    /// Seed of the poses and scenes.
    pub seed: u64,
    /// The backgrounds.
    pub backgrounds: Vec<String>,
    /// Which database ("default" or "imaging-aware").
    pub database: &'static str,
    /// What its confidence network reads ("features", "response" or
    /// "grounded").
    pub confidence_input: &'static str,
    /// The rows, clean first.
    pub rows: Vec<RobustRow>,
    /// Time of the whole protocol, s.
    pub total_seconds: f64,
}

/// The scene configuration of `family` at `level` (None: clean).
/// The motion blur family's direction: neither along the image's rows nor
/// its columns, where an object's printed bands would hide it.
const MOTION_BLUR_DEG: f32 = 30.0;

/// The sensor noise family's read noise, electrons (a phone-class sensor's
/// 2-5).
const READ_NOISE_E: f32 = 3.0;

/// The population the `occluding_object` family's occluders are drawn
/// from (`generated-999000` ..): one no protocol measures by default.
const OCCLUDER_POPULATION: u64 = 999;

/// The object that hides the target in the `occluding_object` family's
/// scenes of `scene_seed`: a generated object of [`OCCLUDER_POPULATION`].
fn occluder_for(scene_seed: u64) -> Result<Arc<Object>, EvalError> {
    let name = format!(
        "{}{}",
        acch_capture::GENERATED_PREFIX,
        OCCLUDER_POPULATION * 1000 + scene_seed % 1000
    );
    Ok(Arc::new(Object::builtin(&name)?))
}

/// The scene of `config` under `condition`; `scene_seed` draws the
/// occluding object.
fn perturbed(
    mut config: SceneConfig,
    condition: Option<(&str, f64)>,
    scene_seed: u64,
) -> Result<SceneConfig, EvalError> {
    let fx = &mut config.effects;
    match condition {
        None => {}
        Some(("exposure", v)) => fx.exposure = v as f32,
        Some(("brightness", v)) => fx.brightness = v as f32,
        Some(("colour_temperature", v)) => fx.colour_temp_k = v as f32,
        Some(("noise", v)) => fx.noise_sigma = v as f32,
        Some(("blur", v)) => fx.blur_sigma = v as f32,
        Some(("jpeg", v)) => fx.jpeg_quality = v as u8,
        Some(("motion_blur", v)) => {
            fx.motion_blur_px = v as f32;
            fx.motion_blur_deg = MOTION_BLUR_DEG;
        }
        Some(("sensor_noise", v)) => {
            fx.full_well_e = v as f32;
            fx.read_noise_e = READ_NOISE_E;
        }
        Some(("occlusion", v)) => config.occlusion = v as f32,
        Some(("occluding_object", v)) => {
            config.occlusion = v as f32;
            config.occluder = Some(occluder_for(scene_seed)?);
        }
        Some(("light_direction", v)) => config.light_azimuth_deg = v as f32,
        // The camera's distance is the view's, not the scene's.
        Some(_) => {}
    }
    Ok(config)
}

/// The scenes the robust protocol draws for one object on one background:
/// poses and a render seed of their own per object and background, so the
/// backgrounds do not repeat one pose and objects do not share poses.
pub struct SceneDraw {
    /// The clean scene (the object on the background, held-out textures).
    pub scene: SceneConfig,
    /// The camera's poses.
    pub views: Vec<acch_capture::ViewPose>,
    /// The renderer's seed (each view's frame seed derives from it).
    pub render_seed: u64,
}

impl SceneDraw {
    /// The draw of `--seed seed` for `object` on background `b` (an index
    /// into A, B, C), `n` poses.
    pub fn new(object: &Arc<Object>, seed: u64, b: usize, n: usize) -> Result<Self, EvalError> {
        let salt = name_salt(object.name());
        let background: Background = BACKGROUNDS[b].parse()?;
        Ok(SceneDraw {
            scene: SceneConfig::new(object.clone(), background).with_textures(TextureSet::HeldOut),
            views: ViewSpec::Random { n }.views(
                DEFAULT_DISTANCE,
                protocol::scene_seed(seed, b, salt, 0x706f_7365),
            ),
            render_seed: protocol::scene_seed(seed, b, salt, 0x726f_6275),
        })
    }
}

/// Runs the robust protocol for `object` on its default database `db`.
pub fn robust(
    object: Arc<Object>,
    (db, smoothed): (&ViewDatabase, Option<&ViewDatabase>),
    options: &RobustOptions,
) -> Result<RobustReport, EvalError> {
    let o = options;
    if o.n == 0 {
        return Err(EvalError::Input("--n must be at least 1".into()));
    }
    if let Some(bad) = o
        .families
        .iter()
        .find(|f| !FAMILIES.iter().any(|k| k.name == *f))
    {
        let names: Vec<&str> = FAMILIES.iter().map(|f| f.name).collect();
        return Err(EvalError::Input(format!(
            "--families: no family '{bad}' (there are {})",
            names.join(", ")
        )));
    }
    let start = Instant::now();
    // Poses (and scenes, below) of their own for every object and
    // background: with one draw for all, a population of 53 objects at
    // --n 2 was measured on two poses, and the three backgrounds gave one
    // estimate thrice.
    let draws = (0..BACKGROUNDS.len())
        .map(|b| SceneDraw::new(&object, o.seed, b, o.n))
        .collect::<Result<Vec<_>, _>>()?;
    let mut conditions: Vec<Option<(&str, f64)>> = vec![None];
    for f in FAMILIES
        .iter()
        .filter(|f| o.families.is_empty() || o.families.iter().any(|n| n == f.name))
    {
        conditions.extend(f.levels.iter().map(|&l| Some((f.name, l))));
    }
    let searches: &[usize] = if o.compare {
        &[SINGLE_IMAGE_LIGHT_SEARCH, 0]
    } else {
        &[SINGLE_IMAGE_LIGHT_SEARCH]
    };
    let bar = protocol::progress((conditions.len() * BACKGROUNDS.len()) as u64, "conditions");
    let trained = acch_pose::PoseEstimator::new(db.clone())?;
    let mut rows = Vec::new();
    for condition in &conditions {
        let distance = match condition {
            Some(("distance", v)) => *v,
            _ => 1.0,
        };
        let mut scenes = Vec::new();
        for draw in &draws {
            let seed = draw.render_seed;
            let renderer = Renderer::new(perturbed(draw.scene.clone(), *condition, seed)?, seed);
            let set: Vec<Rendered> = draw
                .views
                .par_iter()
                .enumerate()
                .map(|(i, v)| -> Result<Rendered, EvalError> {
                    let v = acch_capture::ViewPose {
                        distance: v.distance * distance,
                        ..*v
                    };
                    Ok(renderer.render(&v, acch_capture::frame_seed(seed, i)))
                })
                .collect::<Result<_, _>>()?;
            scenes.extend(set);
            bar.inc(1);
        }
        for &search in searches {
            let distance_m = db.train_distance_m as f64 * distance;
            let sets = (db, smoothed);
            let mut row = measure(
                sets,
                &trained,
                &scenes,
                object.radius_m(),
                distance_m,
                search,
            )?;
            let (family, level) = condition.unwrap_or(("clean", 0.0));
            row.family = family.to_owned();
            row.level = level;
            rows.push(row);
        }
    }
    bar.finish_and_clear();
    Ok(RobustReport {
        protocol: "robust",
        object: object.name().to_owned(),
        n: o.n,
        seed: o.seed,
        backgrounds: BACKGROUNDS.iter().map(|b| b.to_string()).collect(),
        database: o.database,
        confidence_input: acch_confidence::Model::load(db)
            .map_or("none", |m| acch_train::confidence::kind_name(m.kind())),
        rows,
        total_seconds: start.elapsed().as_secs_f64(),
    })
}

/// The chain over `scenes`, in parallel (each image is searched afresh,
/// so the order does not matter); the row's family is left to the caller.
/// `trained` is an estimator over `db`, for how alike its views are.
fn measure(
    (db, smoothed): (&ViewDatabase, Option<&ViewDatabase>),
    trained: &acch_pose::PoseEstimator,
    scenes: &[Rendered],
    radius_m: f64,
    distance_m: f64,
    light_search: usize,
) -> Result<RobustRow, EvalError> {
    let images: Vec<ImageOutcome> = scenes
        .par_iter()
        .enumerate()
        .map_init(
            || {
                (
                    protocol::chain_for_sets(db, smoothed, distance_m, light_search),
                    acch_core::QualityMeter::new(),
                    vec![0f32; db.views().len()],
                )
            },
            |(chain, meter, alike), (i, scene)| -> Result<_, EvalError> {
                let chain = chain
                    .as_mut()
                    .map_err(|e| EvalError::Worker(e.to_string()))?;
                let (w, h) = scene.image.dimensions();
                let quality = meter.measure(scene.image.as_raw(), w, h);
                let out = chain.process(
                    &protocol::frame_of(scene, i as u64, false, radius_m),
                    scene.image.as_raw(),
                );
                let t = &scene.truth;
                let truth = (t.theta_deg as f32, t.phi_deg as f32);
                let posed = out.pose().done();
                let estimate = posed.map(|e| (e.theta_deg, e.phi_deg));
                let verdict = out.rating().verdict();
                let rival = chain.last_response().and_then(|r| {
                    let response: Vec<f32> = r.values().collect();
                    acch_confidence::rival_ratio(
                        &response,
                        db.views(),
                        acch_confidence::DEFAULT_MIN_PHI_SEPARATION_DEG,
                        protocol::failure_rule().theta_deg,
                    )
                    .ok()
                });
                // How the truth's own training view rates the view chosen:
                // what the database could tell apart at best.
                let look_alike = posed.map(|e| {
                    trained.respond_to_view(protocol::nearest_view(db, truth), alike);
                    alike[e.best_view as usize]
                });
                Ok(ImageOutcome {
                    truth,
                    estimate,
                    look_alike,
                    failed: estimate.is_none_or(|e| fails(e, truth)),
                    accepted: estimate.is_some() && verdict.is_some_and(|v| v.accepted),
                    match_value: posed.map(|e| e.best_value),
                    confidence: verdict.map(|v| v.confidence),
                    rival,
                    phi_plateau_deg: verdict.map(|v| v.phi_plateau_deg),
                    map_rival: verdict.map(|v| v.map_rival).filter(|r| r.is_finite()),
                    score_margin: out.detection().done().map(|w| w.margin()),
                    quality,
                    set: out.envelope().imaging.set,
                    object_sharpness: out.envelope().imaging.object_sharpness,
                })
            },
        )
        .collect::<Result<_, _>>()?;
    let n = scenes.len();
    let estimates: Vec<((f32, f32), (f32, f32))> = images
        .iter()
        .filter_map(|o| o.estimate.map(|e| (e, o.truth)))
        .collect();
    let found = estimates.len();
    let failed = images.iter().filter(|o| o.failed).count();
    let accepted: Vec<&ImageOutcome> = images.iter().filter(|o| o.accepted).collect();
    let share = |k: usize, of: usize| k as f64 / of.max(1) as f64;
    // 0 with no estimate (an empty float sum is -0, printed "-0.00°").
    let mean = |f: fn((f32, f32), (f32, f32)) -> f32| {
        let sum: f64 = estimates.iter().map(|&(e, t)| f(e, t) as f64).sum();
        if found == 0 { 0.0 } else { sum / found as f64 }
    };
    Ok(RobustRow {
        family: String::new(),
        level: 0.0,
        light_search: light_search > 0,
        n,
        not_found_rate: share(n - found, n),
        failure_rate: share(failed, n),
        accepted_rate: share(accepted.len(), n),
        acc_failure_rate: share(accepted.iter().filter(|e| e.failed).count(), accepted.len()),
        mean_phi_err_deg: mean(|e, t| phi_error(e.1, t.1)),
        mean_theta_err_deg: mean(|e, t| (e.0 - t.0).abs()),
        images,
    })
}

/// The robust protocol over a population of objects: the rows of every
/// object's report pooled per family and level, with the spread over the
/// objects.
#[derive(Serialize, Debug)]
pub struct PopulationReport {
    /// "robust-population".
    pub protocol: &'static str,
    /// The objects, in order.
    pub objects: Vec<String>,
    /// Test poses per background and object.
    pub n: usize,
    /// Seed of the poses and scenes.
    pub seed: u64,
    /// Which databases ("default" or "imaging-aware").
    pub database: &'static str,
    /// The pooled rows, clean first.
    pub rows: Vec<PopulationRow>,
    /// Every object's own report.
    pub per_object: Vec<RobustReport>,
    /// Time of the whole protocol (training included), s.
    pub total_seconds: f64,
}

/// A family at a level pooled over the population: the rates are over
/// all its images (`n` of them), the spread over its objects.
#[derive(Clone, Debug, Serialize)]
pub struct PopulationRow {
    /// The pooled rates, as one object's row holds them.
    #[serde(flatten)]
    pub pooled: RobustRow,
    /// Objects pooled.
    pub objects: usize,
    /// The worst object's failure rate.
    pub worst_failure_rate: f64,
    /// The worst object's failures among its accepted.
    pub worst_acc_failure_rate: f64,
    /// Objects with any accepted estimate wrong.
    pub objects_accepting_wrong: usize,
}

impl PopulationRow {
    /// Pools the rows of one family, level and search over the objects.
    fn pool(rows: &[&RobustRow]) -> PopulationRow {
        let first = rows[0];
        let n: usize = rows.iter().map(|r| r.n).sum();
        // The rates are shares of whole images: back to counts exactly.
        let count = |rate: f64, of: usize| (rate * of as f64).round() as usize;
        let sum = |f: &dyn Fn(&RobustRow) -> usize| rows.iter().map(|r| f(r)).sum::<usize>();
        let not_found = sum(&|r| count(r.not_found_rate, r.n));
        let failed = sum(&|r| count(r.failure_rate, r.n));
        let accepted = sum(&|r| count(r.accepted_rate, r.n));
        let acc_failed = sum(&|r| count(r.acc_failure_rate, count(r.accepted_rate, r.n)));
        let found = n - not_found;
        let mean = |f: &dyn Fn(&RobustRow) -> f64| {
            rows.iter()
                .map(|r| f(r) * (r.n - count(r.not_found_rate, r.n)) as f64)
                .sum::<f64>()
                / found.max(1) as f64
        };
        let share = |k: usize, of: usize| k as f64 / of.max(1) as f64;
        let worst = |f: &dyn Fn(&RobustRow) -> f64| rows.iter().map(|r| f(r)).fold(0.0, f64::max);
        PopulationRow {
            pooled: RobustRow {
                family: first.family.clone(),
                level: first.level,
                light_search: first.light_search,
                n,
                not_found_rate: share(not_found, n),
                failure_rate: share(failed, n),
                accepted_rate: share(accepted, n),
                acc_failure_rate: share(acc_failed, accepted),
                mean_phi_err_deg: mean(&|r| r.mean_phi_err_deg),
                mean_theta_err_deg: mean(&|r| r.mean_theta_err_deg),
                images: Vec::new(),
            },
            objects: rows.len(),
            worst_failure_rate: worst(&|r| r.failure_rate),
            worst_acc_failure_rate: worst(&|r| r.acc_failure_rate),
            objects_accepting_wrong: rows.iter().filter(|r| r.acc_failure_rate > 0.0).count(),
        }
    }
}

/// Runs the robust protocol on every object of `population` with its
/// database (`database(object)`, trained on first use), and pools the rows.
pub fn robust_population(
    population: &[Arc<Object>],
    database: &dyn Fn(&Arc<Object>) -> Result<Databases, EvalError>,
    options: &RobustOptions,
) -> Result<PopulationReport, EvalError> {
    if population.is_empty() {
        return Err(EvalError::Input("the population holds no object".into()));
    }
    let start = Instant::now();
    let bar = protocol::progress(population.len() as u64, "objects");
    let mut per_object = Vec::with_capacity(population.len());
    for object in population {
        bar.set_message(format!("objects ({})", object.name()));
        let (db, smoothed) = database(object)?;
        per_object.push(robust(object.clone(), (&db, smoothed.as_ref()), options)?);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let rows = per_object[0]
        .rows
        .iter()
        .enumerate()
        .map(|(k, _)| {
            let rows: Vec<&RobustRow> = per_object.iter().map(|r| &r.rows[k]).collect();
            PopulationRow::pool(&rows)
        })
        .collect();
    Ok(PopulationReport {
        protocol: "robust-population",
        objects: population.iter().map(|o| o.name().to_owned()).collect(),
        n: options.n,
        seed: options.seed,
        database: options.database,
        rows,
        per_object,
        total_seconds: start.elapsed().as_secs_f64(),
    })
}

impl PopulationReport {
    /// Writes the report as JSON.
    pub fn write_json(&self, path: &Path) -> Result<(), EvalError> {
        write_json(path, self)
    }

    /// Writes every object's images' truth, estimate and outcome as CSV.
    pub fn write_errors(&self, path: &Path) -> Result<(), EvalError> {
        write_errors(path, &self.per_object)
    }

    /// Plots the pooled failure rate and the failures among the accepted
    /// against the level, one panel per family (the light search's rows).
    pub fn write_plot(&self, path: &Path) -> Result<(), EvalError> {
        let search = self.rows.iter().any(|r| r.pooled.light_search);
        let rows: Vec<&PopulationRow> = self
            .rows
            .iter()
            .filter(|r| r.pooled.light_search == search)
            .collect();
        let clean = rows.iter().find(|r| r.pooled.family == "clean");
        type Rate = fn(&PopulationRow) -> f64;
        let measures: [(&str, Rate); 3] = [
            ("failures", |r| r.pooled.failure_rate),
            ("wrong among accepted", |r| r.pooled.acc_failure_rate),
            ("worst object's failures", |r| r.worst_failure_rate),
        ];
        let panels: Vec<acch_viz::plot::Panel> = FAMILIES
            .iter()
            .filter(|f| rows.iter().any(|r| r.pooled.family == f.name))
            .map(|f| acch_viz::plot::Panel {
                title: format!("{} ({})", f.name.replace('_', " "), f.unit),
                series: measures
                    .iter()
                    .map(|(name, rate)| acch_viz::plot::Series {
                        name: (*name).into(),
                        points: rows
                            .iter()
                            .filter(|r| r.pooled.family == f.name)
                            .map(|r| (r.pooled.level, rate(r)))
                            .collect(),
                        reference: clean.map(|r| rate(r)),
                    })
                    .collect(),
            })
            .collect();
        acch_viz::plot::panels(
            path,
            &format!(
                "{} generated and other objects, {} views each on A, B, C: rates by perturbation",
                self.objects.len(),
                self.n
            ),
            "rate",
            &panels,
        )?;
        Ok(())
    }

    /// Prints the pooled table.
    pub fn print(&self) {
        println!(
            "robust protocol over {} objects ({} .. {}), {} poses on each of A, B, C (seed {}), {} databases",
            self.objects.len(),
            self.objects.first().map_or("", String::as_str),
            self.objects.last().map_or("", String::as_str),
            self.n,
            self.seed,
            self.database
        );
        println!(
            "{:<20} {:>7} {:>6} {:>6} {:>7} {:>7} {:>8} {:>7} {:>7} {:>9} {:>7}",
            "family",
            "level",
            "search",
            "lost",
            "fail",
            "accept",
            "accfail",
            "E(phi)",
            "E(th)",
            "worstfail",
            "objwrong"
        );
        for row in &self.rows {
            let r = &row.pooled;
            println!(
                "{:<20} {:>7} {:>6} {:>5.1}% {:>6.1}% {:>6.1}% {:>7.1}% {:>6.2}° {:>6.2}° {:>8.1}% {:>7}",
                r.family,
                r.level,
                if r.light_search { "yes" } else { "no" },
                100.0 * r.not_found_rate,
                100.0 * r.failure_rate,
                100.0 * r.accepted_rate,
                100.0 * r.acc_failure_rate,
                r.mean_phi_err_deg,
                r.mean_theta_err_deg,
                100.0 * row.worst_failure_rate,
                row.objects_accepting_wrong
            );
        }
        println!(
            "pooled over the objects' images; worstfail: the worst object's failure rate; objwrong: objects with an accepted estimate wrong. {:.0} s",
            self.total_seconds
        );
    }
}

impl RobustReport {
    /// Writes the report as JSON.
    pub fn write_json(&self, path: &Path) -> Result<(), EvalError> {
        write_json(path, self)
    }

    /// Writes every image's truth, estimate and outcome as CSV.
    pub fn write_errors(&self, path: &Path) -> Result<(), EvalError> {
        write_errors(path, std::slice::from_ref(self))
    }

    /// Appends this report's images to `csv`, one line each.
    fn errors_csv(&self, csv: &mut String) {
        use std::fmt::Write as _;
        let opt = |v: Option<f32>| v.map_or(String::new(), |v| format!("{v:.3}"));
        for r in &self.rows {
            for (i, o) in r.images.iter().enumerate() {
                let e = o.estimate;
                let _ = writeln!(
                    csv,
                    "{},{},{},{},{},{},{:.3},{:.3},{},{},{},{},{},{},{},{},{},{},{:.3},{:.3},{:.3},{},{:.3},{},{},{}",
                    self.object,
                    r.family,
                    r.level,
                    r.light_search as u8,
                    self.backgrounds[(i / self.n.max(1)).min(self.backgrounds.len() - 1)],
                    i % self.n.max(1),
                    o.truth.0,
                    o.truth.1,
                    opt(e.map(|e| e.0)),
                    opt(e.map(|e| e.1)),
                    opt(e.map(|e| (e.0 - o.truth.0).abs())),
                    opt(e.map(|e| phi_error(e.1, o.truth.1))),
                    o.failed as u8,
                    o.accepted as u8,
                    opt(o.match_value),
                    opt(o.confidence),
                    opt(o.rival),
                    opt(o.score_margin),
                    o.quality.noise_sigma,
                    o.quality.blockiness,
                    o.quality.sharpness,
                    o.set.name(),
                    o.object_sharpness,
                    opt(o.look_alike),
                    opt(o.phi_plateau_deg),
                    opt(o.map_rival),
                );
            }
        }
    }

    /// Plots the failure rate against the level, one panel per family,
    /// with and without the light search.
    pub fn write_plot(&self, path: &Path) -> Result<(), EvalError> {
        let clean = |search: bool| {
            self.rows
                .iter()
                .find(|r| r.family == "clean" && r.light_search == search)
                .map(|r| r.failure_rate)
        };
        let panels: Vec<acch_viz::plot::Panel> = FAMILIES
            .iter()
            .filter(|f| self.rows.iter().any(|r| r.family == f.name))
            .map(|f| acch_viz::plot::Panel {
                title: format!("{} ({})", f.name.replace('_', " "), f.unit),
                series: [true, false]
                    .into_iter()
                    .filter(|s| clean(*s).is_some())
                    .map(|search| acch_viz::plot::Series {
                        name: if search {
                            "light search"
                        } else {
                            "training light only"
                        }
                        .into(),
                        points: self
                            .rows
                            .iter()
                            .filter(|r| r.family == f.name && r.light_search == search)
                            .map(|r| (r.level, r.failure_rate))
                            .collect(),
                        reference: clean(search),
                    })
                    .collect(),
            })
            .collect();
        acch_viz::plot::panels(
            path,
            &format!(
                "{}: failures (wrong or not found) by perturbation, {} views on A, B, C",
                self.object,
                self.rows.first().map_or(0, |r| r.n)
            ),
            "failure rate",
            &panels,
        )?;
        Ok(())
    }

    /// Prints the table.
    pub fn print(&self) {
        println!(
            "robust protocol: {}, {} poses on each of {} (seed {}), {} database",
            self.object,
            self.n,
            self.backgrounds.join(", "),
            self.seed,
            self.database
        );
        println!(
            "{:<20} {:>7} {:>6} {:>6} {:>7} {:>7} {:>8} {:>7} {:>7}",
            "family", "level", "search", "lost", "fail", "accept", "accfail", "E(phi)", "E(th)"
        );
        for r in &self.rows {
            println!(
                "{:<20} {:>7} {:>6} {:>5.1}% {:>6.1}% {:>6.1}% {:>7.1}% {:>6.2}° {:>6.2}°",
                r.family,
                r.level,
                if r.light_search { "yes" } else { "no" },
                100.0 * r.not_found_rate,
                100.0 * r.failure_rate,
                100.0 * r.accepted_rate,
                100.0 * r.acc_failure_rate,
                r.mean_phi_err_deg,
                r.mean_theta_err_deg
            );
        }
        println!(
            "fail: the paper's rule or not found, before the confidence network; accfail: among the accepted. {:.0} s",
            self.total_seconds
        );
    }
}

/// A number of its own for each object name (FNV-1a: the same in every
/// build, unlike the standard hasher).
fn name_salt(name: &str) -> usize {
    name.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    }) as usize
}

/// The images of `reports` as CSV, one line each.
fn write_errors(path: &Path, reports: &[RobustReport]) -> Result<(), EvalError> {
    let mut csv = String::from(
        "object,family,level,light_search,background,image,theta_deg,phi_deg,est_theta_deg,est_phi_deg,abs_dtheta_deg,abs_dphi_deg,failure,accepted,match_value,confidence,rival,score_margin,noise_sigma,blockiness,sharpness,set,object_sharpness,look_alike,phi_plateau_deg,map_rival\n",
    );
    for r in reports {
        r.errors_csv(&mut csv);
    }
    std::fs::write(path, csv).map_err(|source| EvalError::Io {
        path: path.to_owned(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use acch_capture::Effects;

    #[test]
    fn every_family_changes_the_scene_or_the_view() {
        let object = Arc::new(Object::builtin("fruitbox").unwrap());
        let base = SceneConfig::new(object, "A".parse().unwrap());
        for f in &FAMILIES {
            let changed = perturbed(base.clone(), Some((f.name, f.levels[0])), 7).unwrap();
            let scene_changed = changed.effects != Effects::default()
                || changed.occlusion != base.occlusion
                || changed.light_azimuth_deg != base.light_azimuth_deg;
            assert_eq!(scene_changed, f.name != "distance", "{}", f.name);
        }
    }
}
