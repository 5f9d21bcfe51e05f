//! The paper's table 1: pose with ground-truth masks. Train on the paper's
//! grid on the plain background, test on random poses off the grid; the
//! deployed pose stage estimates each from the image quantised with the
//! database's palette and the true mask, as segmentation would hand it.
//! Variants (with `compare`) change one thing each: histogram kind,
//! annulus, palette space, offsets, refinement, scale from the ROI.

use crate::protocol::{self, PAPER_GRID, fails};
use crate::{EvalError, write_json};
use acch_capture::{
    Background, DEFAULT_DISTANCE, Object, Rendered, TextureSet, ViewPose, ViewSpec,
};
use acch_core::{HistogramKind, IndexImage, ViewDatabase};
use acch_pipeline::stages::{Pose, Segmented};
use acch_pipeline::wire::{Intrinsics, Outcome};
use acch_pipeline::{FrameHeader, Stage, StageSettings};
use acch_pose::train::{LabelledView, TrainConfig};
use acch_pose::{Refinement, phi_error};
use acch_train::views::train_views;
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Options of table 1.
#[derive(Clone, Debug)]
pub struct Table1Options {
    /// Test poses.
    pub n: usize,
    /// Seed of the test poses and the scene (training views use seed 0).
    pub seed: u64,
    /// Also evaluate the variants.
    pub compare: bool,
    /// The test views' camera roll, uniform in ±this, degrees (0: none).
    pub roll_deg: f64,
    /// The largest roll the pose stage searches, degrees (0: none).
    pub roll_search_deg: f64,
}

/// Accuracy of one configuration over a test set.
#[derive(Clone, Debug, Serialize)]
pub struct Metrics {
    /// Configuration name.
    pub name: String,
    /// Test images.
    pub n: usize,
    /// Mean |Δφ| (wrapped) over the estimates made, degrees.
    pub mean_phi_err_deg: f64,
    /// Mean |Δθ| over the estimates made, degrees.
    pub mean_theta_err_deg: f64,
    /// Share of images with |Δθ| > 10° or |Δφ| > 20°, or no estimate.
    pub failure_rate: f64,
    /// Mean time of one estimate (quantise, histogram, response, refine), ms.
    pub ms_per_estimate: f64,
    /// Mean |Δroll| over the estimates made, degrees (the roll is 0 when
    /// not searched).
    pub mean_roll_err_deg: f64,
    /// Mean turn of the estimated camera about its optical axis against
    /// the truth ([`protocol::turn_error_deg`]), degrees.
    pub mean_turn_err_deg: f64,
    /// Share of images whose estimated camera rotation (θ, φ and roll
    /// together) is within 10° of the truth: near θ = 90° a turn in φ and
    /// a roll are the same rotation, which this counts once.
    pub rotation_within_10deg: f64,
}

/// One test image's outcome.
#[derive(Clone, Debug)]
pub struct ErrorRow {
    /// True elevation and azimuth, degrees.
    pub truth: (f32, f32),
    /// Estimated elevation and azimuth, if any.
    pub estimate: Option<(f32, f32)>,
    /// True and estimated camera roll, degrees (the estimate's is 0
    /// without the search).
    pub roll: (f32, f32),
    /// Best match value.
    pub best_value: f32,
}

/// Table 1's report.
#[derive(Serialize, Debug)]
pub struct Table1Report {
    /// "table1".
    pub protocol: &'static str,
    /// The object.
    pub object: String,
    /// Test images.
    pub n: usize,
    /// The main row's mean |Δφ|, degrees.
    pub mean_phi_err_deg: f64,
    /// The main row's mean |Δθ|, degrees.
    pub mean_theta_err_deg: f64,
    /// The main row's failure rate.
    pub failure_rate: f64,
    /// Mean distance of the test poses to the nearest grid φ: the error of
    /// a perfect winner-takes-all estimate.
    pub floor_phi_deg: f64,
    /// The same for θ.
    pub floor_theta_deg: f64,
    /// The main row's time per estimate, ms.
    pub ms_per_estimate: f64,
    /// Training views.
    pub train_views: usize,
    /// Time to train the main row's database, s.
    pub train_seconds: f64,
    /// Time of the whole protocol, s.
    pub total_seconds: f64,
    /// Every row, the main one first.
    pub variants: Vec<Metrics>,
    /// The main row's per-image outcomes.
    #[serde(skip)]
    pub errors: Vec<ErrorRow>,
}

struct Variant {
    name: String,
    config: TrainConfig,
    refinement: Refinement,
    /// Scale from the known distance (else from the ROI).
    known_distance: bool,
    /// The roll the pose stage searches, degrees.
    roll_search_deg: f64,
}

/// Runs table 1 for `object` with histogram options `base`.
pub fn table1(
    object: Arc<Object>,
    o: &Table1Options,
    base: &TrainConfig,
) -> Result<Table1Report, EvalError> {
    if o.n == 0 {
        return Err(EvalError::Input("--n must be at least 1".into()));
    }
    let start = Instant::now();
    let plain: Background = "plain".parse()?;
    let renderer = protocol::renderer(object.clone(), plain, TextureSet::Training, o.seed);
    let grid: ViewSpec = PAPER_GRID.parse()?;
    let train_views_list = grid.views(DEFAULT_DISTANCE, 0);
    let test_views = protocol::rolled(off_grid_random(&grid, o.n, o.seed), o.roll_deg, o.seed)?;
    let train = protocol::render_views(&renderer, &train_views_list, 0, "train views");
    let test = protocol::render_views(&renderer, &test_views, o.seed, "test views");

    let variant = |name: &str, f: &dyn Fn(&mut TrainConfig)| {
        let mut config = base.clone();
        f(&mut config);
        Variant {
            name: name.into(),
            config,
            refinement: Refinement::Parabolic,
            known_distance: true,
            roll_search_deg: o.roll_search_deg,
        }
    };
    let mut variants = vec![variant("acch refined", &|_| {})];
    if o.compare {
        variants.push(Variant {
            refinement: Refinement::WinnerTakesAll,
            ..variant("acch winner-takes-all", &|_| {})
        });
        variants.push(variant("cch", &|c| c.params.kind = HistogramKind::Cch));
        variants.push(variant("dcch", &|c| c.params.kind = HistogramKind::Dcch));
        variants.push(variant("acch local 0<r<=20", &|c| c.params.r_min = 0.0));
        variants.push(variant("acch rgb palette", &|c| {
            c.space = acch_core::ColourSpace::Rgb
        }));
        variants.push(Variant {
            known_distance: false,
            ..variant("acch scale from roi", &|_| {})
        });
        variants.push(variant("acch dense stride 1", &|c| {
            c.params.sampling = acch_core::OffsetSampling::Dense;
            c.params.stride = 1;
        }));
    }

    let labelled: Vec<LabelledView> = train
        .iter()
        .map(|r| protocol::labelled(r, DEFAULT_DISTANCE))
        .collect();
    let mut results = Vec::new();
    let mut errors = Vec::new();
    let mut train_seconds = 0.0;
    for v in &variants {
        let t = Instant::now();
        let db = train_views(
            object.name(),
            (DEFAULT_DISTANCE * object.radius_m()) as f32,
            &labelled,
            &v.config,
        )?;
        if results.is_empty() {
            train_seconds = t.elapsed().as_secs_f64();
        }
        let (metrics, rows) = evaluate(&v.name, &db, &test, v)?;
        if results.is_empty() {
            errors = rows;
        }
        results.push(metrics);
    }
    let (floor_phi, floor_theta) = floors(&grid, &test_views);
    let main = &results[0];
    Ok(Table1Report {
        protocol: "table1",
        object: object.name().to_owned(),
        n: main.n,
        mean_phi_err_deg: main.mean_phi_err_deg,
        mean_theta_err_deg: main.mean_theta_err_deg,
        failure_rate: main.failure_rate,
        floor_phi_deg: floor_phi,
        floor_theta_deg: floor_theta,
        ms_per_estimate: main.ms_per_estimate,
        train_views: train_views_list.len(),
        train_seconds,
        total_seconds: start.elapsed().as_secs_f64(),
        variants: results,
        errors,
    })
}

impl Table1Report {
    /// Prints the table.
    pub fn print(&self) {
        println!(
            "table1 · {} · {} test poses, {} training views · winner-takes-all floor: φ {:.2}°, θ {:.2}°",
            self.object, self.n, self.train_views, self.floor_phi_deg, self.floor_theta_deg
        );
        println!(
            "{:<24} {:>5} {:>9} {:>9} {:>9} {:>9} {:>9} {:>8} {:>8}",
            "variant", "n", "E(phi)", "E(theta)", "E(roll)", "E(turn)", "failures", "rot<=10", "ms"
        );
        for m in &self.variants {
            println!(
                "{:<24} {:>5} {:>8.2}° {:>8.2}° {:>8.2}° {:>8.2}° {:>8.1}% {:>7.1}% {:>8.2}",
                m.name,
                m.n,
                m.mean_phi_err_deg,
                m.mean_theta_err_deg,
                m.mean_roll_err_deg,
                m.mean_turn_err_deg,
                100.0 * m.failure_rate,
                100.0 * m.rotation_within_10deg,
                m.ms_per_estimate
            );
        }
        println!("total {:.1} s", self.total_seconds);
    }

    /// Writes the report as JSON.
    pub fn write_json(&self, path: &Path) -> Result<(), EvalError> {
        write_json(path, self)
    }

    /// Writes the main row's per-image outcomes as CSV.
    pub fn write_errors(&self, path: &Path) -> Result<(), EvalError> {
        use std::fmt::Write as _;
        let mut s = String::from(
            "index,theta_deg,phi_deg,est_theta_deg,est_phi_deg,abs_dtheta_deg,abs_dphi_deg,match,failure,roll_deg,est_roll_deg,rotation_err_deg\n",
        );
        for (i, r) in self.errors.iter().enumerate() {
            let _ = match r.estimate {
                Some((t, p)) => {
                    let (dt, dp) = ((t - r.truth.0).abs(), phi_error(p, r.truth.1));
                    let rotation = protocol::rotation_error_deg(
                        [t as f64, p as f64, r.roll.1 as f64],
                        [r.truth.0 as f64, r.truth.1 as f64, r.roll.0 as f64],
                    );
                    writeln!(
                        s,
                        "{i},{:.3},{:.3},{t:.3},{p:.3},{dt:.3},{dp:.3},{:.5},{},{:.3},{:.3},{rotation:.3}",
                        r.truth.0,
                        r.truth.1,
                        r.best_value,
                        fails((t, p), r.truth) as u8,
                        r.roll.0,
                        r.roll.1
                    )
                }
                None => writeln!(
                    s,
                    "{i},{:.3},{:.3},,,,,,1,{:.3},,",
                    r.truth.0, r.truth.1, r.roll.0
                ),
            };
        }
        std::fs::write(path, s).map_err(|source| EvalError::Io {
            path: path.to_owned(),
            source,
        })
    }
}

/// `n` random poses (θ in [45, 90], φ in [0, 360)) none of which falls on
/// a grid point.
fn off_grid_random(grid: &ViewSpec, n: usize, seed: u64) -> Vec<ViewPose> {
    let on_grid = grid.views(DEFAULT_DISTANCE, 0);
    let mut out = Vec::with_capacity(n);
    let mut round = 0u64;
    while out.len() < n {
        let candidates =
            ViewSpec::Random { n }.views(DEFAULT_DISTANCE, seed.wrapping_add(round * 7919));
        for v in candidates {
            let on = on_grid.iter().any(|g| {
                (g.theta_deg - v.theta_deg).abs() < 1e-6
                    && phi_error(g.phi_deg as f32, v.phi_deg as f32) < 1e-4
            });
            if !on && out.len() < n {
                out.push(v);
            }
        }
        round += 1;
    }
    out
}

/// The winner-takes-all floor: mean distance of the test poses to the
/// nearest grid θ and grid φ.
fn floors(grid: &ViewSpec, tests: &[ViewPose]) -> (f64, f64) {
    let on_grid = grid.views(DEFAULT_DISTANCE, 0);
    let n = tests.len() as f64;
    let nearest = |f: &dyn Fn(&ViewPose, &ViewPose) -> f64| {
        tests
            .iter()
            .map(|t| {
                on_grid
                    .iter()
                    .map(|g| f(g, t))
                    .fold(f64::INFINITY, f64::min)
            })
            .sum::<f64>()
            / n
    };
    (
        nearest(&|g, t| phi_error(g.phi_deg as f32, t.phi_deg as f32) as f64),
        nearest(&|g, t| (g.theta_deg - t.theta_deg).abs()),
    )
}

/// Estimates every test view with its ground-truth mask through the pose
/// stage, single-threaded so the time per estimate is a real one.
fn evaluate(
    name: &str,
    db: &ViewDatabase,
    tests: &[Rendered],
    v: &Variant,
) -> Result<(Metrics, Vec<ErrorRow>), EvalError> {
    let (w, h) = tests.first().map_or((640, 480), |r| r.image.dimensions());
    let settings = StageSettings {
        width: w,
        height: h,
        distance_m: v.known_distance.then_some(db.train_distance_m as f64),
        unrated: true,
        roll_search_deg: v.roll_search_deg as f32,
        light_search: 0,
        verify_shape: true,
    };
    let mut pose = Pose::new(db, &settings)?.with_refinement(v.refinement);
    let mut index = IndexImage::default();
    let mut region = vec![0u8; 2 * w as usize * h as usize];
    let mut response = vec![0u8; pose.max_payload()];
    let mut rows = Vec::with_capacity(tests.len());
    let (mut sum_phi, mut sum_theta, mut failures, mut estimated) =
        (0.0f64, 0.0f64, 0usize, 0usize);
    let (mut sum_roll, mut sum_turn) = (0.0f64, 0.0f64);
    let mut rotation_ok = 0usize;
    let mut seconds = 0.0f64;
    for (i, r) in tests.iter().enumerate() {
        let truth = (r.truth.theta_deg as f32, r.truth.phi_deg as f32);
        let t = Instant::now();
        db.palette.quantise_into(r.image.as_raw(), w, h, &mut index);
        let frame = FrameHeader::rgb(i as u64, w, h, Intrinsics::from(&r.truth.intrinsics));
        let given =
            Segmented::from_mask(frame.envelope, r.mask.as_raw(), &index.data, w, &mut region)
                .map_err(|f| EvalError::Input(format!("test view {i}: {f}")))?;
        let Some(header) = given else {
            failures += 1;
            continue;
        };
        let estimate = match pose.process(&header, &region, r.image.as_raw(), &mut response) {
            Ok(Outcome::Done(e)) => Some(e),
            _ => None,
        };
        seconds += t.elapsed().as_secs_f64();
        rows.push(ErrorRow {
            truth,
            estimate: estimate.map(|e| (e.theta_deg, e.phi_deg)),
            roll: (
                r.truth.roll_deg as f32,
                estimate.map_or(0.0, |e| e.roll_deg),
            ),
            best_value: estimate.map_or(0.0, |e| e.best_value),
        });
        match estimate {
            Some(e) => {
                sum_phi += phi_error(e.phi_deg, truth.1) as f64;
                sum_theta += (e.theta_deg - truth.0).abs() as f64;
                sum_roll += protocol::roll_error_deg(e.roll_deg as f64, r.truth.roll_deg);
                let (rotation, true_rotation) = (
                    [e.theta_deg as f64, e.phi_deg as f64, e.roll_deg as f64],
                    [r.truth.theta_deg, r.truth.phi_deg, r.truth.roll_deg],
                );
                let error = protocol::rotation_error_deg(rotation, true_rotation);
                sum_turn += protocol::turn_error_deg(rotation, true_rotation);
                rotation_ok += (error <= 10.0) as usize;
                estimated += 1;
                failures += fails((e.theta_deg, e.phi_deg), truth) as usize;
            }
            None => failures += 1,
        }
    }
    let n = tests.len();
    Ok((
        Metrics {
            name: name.to_owned(),
            n,
            mean_phi_err_deg: sum_phi / estimated.max(1) as f64,
            mean_theta_err_deg: sum_theta / estimated.max(1) as f64,
            failure_rate: failures as f64 / n as f64,
            ms_per_estimate: 1e3 * seconds / n as f64,
            rotation_within_10deg: rotation_ok as f64 / tests.len().max(1) as f64,
            mean_roll_err_deg: sum_roll / estimated.max(1) as f64,
            mean_turn_err_deg: sum_turn / estimated.max(1) as f64,
        },
        rows,
    ))
}
