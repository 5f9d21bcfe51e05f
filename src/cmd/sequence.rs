//! `acch eval --protocol sequence`: temporal fusion and active re-view along
//! camera trajectories, beyond the paper (which proposes both in its
//! conclusion).
//!
//! Training is table 2's recipe (paper grid on the plain background,
//! confidence network on scenes with seeds disjoint from the test scenes),
//! and so are the backgrounds and the failure definition (|Δθ| > 10° or
//! |Δφ| > 20°, nothing estimated counts as a failure), so the figures
//! compare with `--protocol table2`.
//!
//! Fusion: per background, `trajectories` smooth eye-in-hand camera paths
//! (`acch_capture::Trajectory::with_elevation`) of `frames` frames at `fps`,
//! one static scene per path (clutter: one layout per path). By default θ
//! sweeps [20, 90]: a real arm's camera passes below the database's lowest
//! slice (45° for the paper grid), where single frames are wrong or rejected,
//! as in the confidence network's training scenes; `theta_band` (45.5, 89.5)
//! gives the earlier, in-range protocol. Every frame goes through the chain;
//! the arm's motion since the previous frame
//! (`TrajectoryFrame::camera_motion`) drives the filter's prediction, and
//! every accepted estimate, turned into a measurement by `acch_seeding::seed`,
//! its update. An estimate on the database's lowest θ slice is censored
//! (every lower view lands there too): it is fused for φ only
//! (`Measurement::without_theta`).
//!
//! Per frame, the single-frame outcome is the accepted estimate, a failure
//! when wrong (table 2's thresholds) or missing (not found, nothing
//! estimated, rejected by the confidence network: the robot has no pose);
//! the fused outcome is the filter's state after predict + update, a failure
//! when wrong or missing (frames before the first accepted estimate). Both
//! kinds of failure are reported apart (`*_no_answer_rate`, `*_wrong_rate`),
//! as are table 2's own figures over every estimate (`raw_*`).
//!
//! Active re-view: per background, `n` episodes start at random poses with
//! θ in [20, 90] (below the database's 45° too, as the confidence network's
//! training scenes: views it must reject). A rejected view (object not found, nothing estimated, or rated
//! below the confidence threshold) makes the arm move the camera and try
//! again, up to `max_moves` times. The robot knows its elevation over the
//! table (θ, the object standing upright) but not the azimuth φ, so a move
//! is "go to elevation θ', turn by Δφ about the object's vertical axis". An
//! episode succeeds at the first accepted estimate within the failure
//! thresholds; an accepted wrong estimate ends it as a failure (the robot
//! cannot tell). Two policies are measured:
//! - `sweep`: a fixed schedule, Δφ = 45° and θ' cycling 80, 60, 70, 88, 50.
//! - `response`: the most informative next view from the rejected frame's
//!   response. The top views of the response are the azimuth hypotheses;
//!   each candidate move is scored by the mean ambiguity of the database
//!   view every hypothesis would then see (ambiguity of a view: its best
//!   match with a view that counts as a failure, relative to its match with
//!   itself, precomputed over the database), plus a penalty for returning
//!   near a view already tried. Without a response (not found) it falls
//!   back to the sweep.

use super::common;
use super::eval::{FAIL_PHI_DEG, FAIL_THETA_DEG, PAPER_GRID};
use super::table2::BACKGROUNDS;
use crate::model;
use crate::pipeline::{FrameResult, Pipeline};
use acch_capture::{
    Background, DEFAULT_DISTANCE, Intrinsics, Object, Renderer, Trajectory, ViewPose,
};
use acch_core::ViewDatabase;
use acch_pose::phi_error;
use acch_pose::train::TrainConfig;
use acch_seeding::{
    CovarianceModel, Distance, FilterConfig, GridSpacing, Measurement, Outcome, Pinhole, SeedInput,
    ViewFilter, fusion::theta_censored,
};
use anyhow::{Context, Result, bail};
use glam::DVec2;
use indicatif::ProgressBar;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Standard deviation of the known distance handed to the seed, bounding
/// radii (the arm's kinematics).
const DISTANCE_SIGMA: f64 = 0.05;

/// Elevations the sweep policy cycles through, degrees.
const SWEEP_THETA: [f64; 5] = [80.0, 60.0, 70.0, 88.0, 50.0];
/// Azimuth step of the sweep policy, degrees.
const SWEEP_PHI: f64 = 45.0;
/// Candidate elevations of the response policy, degrees.
const CANDIDATE_THETA: [f64; 5] = [50.0, 60.0, 70.0, 80.0, 88.0];
/// Azimuth hypotheses taken from the response.
const HYPOTHESES: usize = 5;
/// Hypotheses must reach this share of the best match value.
const HYPOTHESIS_SHARE: f32 = 0.9;

/// Options of the sequence protocol.
#[derive(Clone, Debug)]
pub struct SequenceOptions {
    /// Trajectories per background.
    pub trajectories: usize,
    /// Frames per trajectory.
    pub frames: usize,
    /// Frame rate of the trajectories (sets how far the arm moves per frame).
    pub fps: f64,
    /// Elevation band the trajectories sweep, degrees (min, max).
    pub theta_band: (f64, f64),
    /// Re-view episodes per background.
    pub episodes: usize,
    /// Moves allowed per episode.
    pub max_moves: usize,
    /// Seed of scenes, trajectories and episode poses.
    pub seed: u64,
    /// Confidence-training scenes per background.
    pub confidence_scenes: usize,
}

/// Fusion results on one background.
///
/// Per frame, the single-frame outcome is the chain's accepted estimate: it
/// fails when it is wrong (|Δθ| > 10° or |Δφ| > 20°, table 2's thresholds)
/// or when there is none (object not found, nothing estimated, or rated
/// below the confidence threshold: the robot gets no pose). The fused
/// outcome is the filter's state after that frame's predict + update: it
/// fails when wrong or when there is none yet (frames before the first
/// accepted estimate). `*_failure_rate` counts both kinds of failure over
/// every frame; `*_no_answer_rate` and `*_wrong_rate` split it;
/// `*_answer_failure_rate` is the failure rate among the answers given.
#[derive(Clone, Debug, Serialize)]
pub struct SequenceRow {
    /// Background name (A, B, C, clutter).
    pub background: String,
    /// Trajectories.
    pub trajectories: usize,
    /// Frames over all trajectories.
    pub frames: usize,
    /// Frames whose true θ lies below the database's lowest view.
    pub below_database_frames: usize,
    /// Frames without a right accepted estimate (none or wrong).
    pub single_failure_rate: f64,
    /// Frames without an accepted estimate.
    pub single_no_answer_rate: f64,
    /// Frames whose accepted estimate is wrong.
    pub single_wrong_rate: f64,
    /// Wrong among accepted estimates.
    pub single_answer_failure_rate: f64,
    /// Mean |Δφ| of accepted estimates, degrees.
    pub single_mean_phi_err_deg: f64,
    /// Mean |Δθ| of accepted estimates, degrees.
    pub single_mean_theta_err_deg: f64,
    /// Frames in which the object was not found or nothing was estimated.
    pub single_not_found: usize,
    /// Frames whose estimate the confidence network rejected.
    pub single_rejected: usize,
    /// Table 2's definition: every estimate, accepted or not, counts; not
    /// found is a failure.
    pub raw_failure_rate: f64,
    /// Mean |Δφ| of every estimate, accepted or not, degrees.
    pub raw_mean_phi_err_deg: f64,
    /// Mean |Δθ| of every estimate, accepted or not, degrees.
    pub raw_mean_theta_err_deg: f64,
    /// Frames without a right fused pose (none yet or wrong).
    pub fused_failure_rate: f64,
    /// Frames before the filter's first accepted estimate (no fused pose).
    pub fused_no_answer_rate: f64,
    /// Frames whose fused pose is wrong.
    pub fused_wrong_rate: f64,
    /// Wrong among fused poses.
    pub fused_answer_failure_rate: f64,
    /// Mean |Δφ| of the fused pose over frames that have one, degrees.
    pub fused_mean_phi_err_deg: f64,
    /// Mean |Δθ| of the fused pose over frames that have one, degrees.
    pub fused_mean_theta_err_deg: f64,
    /// Frames from the filter's first accepted estimate on.
    pub started_frames: usize,
    /// Single-frame failure rate over those frames.
    pub single_failure_rate_started: f64,
    /// Fused failure rate over those frames.
    pub fused_failure_rate_started: f64,
    /// Single-frame failure rate over the frames below the database.
    pub single_failure_rate_below: f64,
    /// Fused failure rate over the frames below the database.
    pub fused_failure_rate_below: f64,
    /// Frames with both an accepted estimate and a fused pose.
    pub paired_frames: usize,
    /// Mean |Δφ| of the single-frame estimate over the paired frames.
    pub paired_single_mean_phi_err_deg: f64,
    /// Mean |Δφ| of the fused pose over the paired frames.
    pub paired_fused_mean_phi_err_deg: f64,
    /// Mean |Δθ| of the single-frame estimate over the paired frames.
    pub paired_single_mean_theta_err_deg: f64,
    /// Mean |Δθ| of the fused pose over the paired frames.
    pub paired_fused_mean_theta_err_deg: f64,
    /// Share of fused frames whose |Δθ| and |Δφ| lie within 2 σ of the
    /// filter's own (θ, φ) covariance (about 0.91 if it were Gaussian and
    /// consistent).
    pub fused_within_2sigma: f64,
    /// Mean reported σ_φ of the fused pose, degrees.
    pub fused_mean_sigma_phi_deg: f64,
    /// Accepted estimates fused.
    pub fused_updates: usize,
    /// Accepted estimates rejected by the gate.
    pub gated: usize,
    /// Of the gated ones, those that were single-frame failures.
    pub gated_failures: usize,
    /// Accepted single-frame failures that the filter fused.
    pub fused_failures: usize,
    /// Restarts of the filter from consistent gated estimates.
    pub reinitialised: usize,
    /// Accepted estimates whose θ is censored (on the database's lowest
    /// slice): fused for φ only.
    pub censored: usize,
    /// Of those, the ones not used because the filter had not started.
    pub censored_unused: usize,
}

/// Re-view results on one background with one policy.
#[derive(Clone, Debug, Serialize)]
pub struct ReviewRow {
    /// Background name.
    pub background: String,
    /// "sweep" or "response".
    pub policy: String,
    /// Episodes.
    pub episodes: usize,
    /// Episodes whose first view was rejected.
    pub initially_rejected: usize,
    /// Episodes whose first view was accepted and right (0 moves).
    pub initially_correct: usize,
    /// Episodes whose first view was accepted and wrong.
    pub initially_wrong: usize,
    /// Of the initially rejected: share that reached an accepted, correct
    /// estimate within the allowed moves.
    pub success_rate: f64,
    /// Moves to success, over the successful initially rejected episodes.
    pub mean_moves: f64,
    /// Median of the same.
    pub median_moves: f64,
    /// Maximum of the same.
    pub max_moves: usize,
    /// Initially rejected episodes that ended on an accepted wrong estimate.
    pub accepted_wrong: usize,
    /// Initially rejected episodes still rejected after every allowed move.
    pub gave_up: usize,
}

#[derive(Serialize)]
struct SequenceReport {
    protocol: &'static str,
    object: String,
    trajectories: usize,
    frames_per_trajectory: usize,
    fps: f64,
    theta_min_deg: f64,
    theta_max_deg: f64,
    database_min_theta_deg: f64,
    episodes: usize,
    max_moves: usize,
    seed: u64,
    filter: FilterConfig,
    confidence_threshold: f32,
    rows: Vec<SequenceRow>,
    review: Vec<ReviewRow>,
    train_seconds: f64,
    total_seconds: f64,
}

/// Everything one frame contributes.
#[derive(Clone, Copy, Debug, Default)]
struct FrameRecord {
    /// True elevation, degrees.
    theta_deg: f64,
    /// |Δθ|, |Δφ| of the single-frame estimate, accepted or not.
    single: Option<(f64, f64)>,
    accepted: bool,
    /// The accepted estimate's θ is censored (on the database's lowest slice).
    censored: bool,
    /// |Δθ|, |Δφ| of the fused pose and its σ_θ, σ_φ.
    fused: Option<(f64, f64, f64, f64)>,
    outcome: Option<Outcome>,
}

fn fails((dtheta, dphi): (f64, f64)) -> bool {
    dtheta > FAIL_THETA_DEG as f64 || dphi > FAIL_PHI_DEG as f64
}

/// Runs the sequence protocol for one object and prints the tables; writes
/// the report as JSON when `json` is given.
pub fn sequence(
    object: Arc<Object>,
    options: &SequenceOptions,
    config: &TrainConfig,
    json: Option<&Path>,
) -> Result<()> {
    let o = options;
    if o.trajectories == 0 || o.frames == 0 {
        bail!(
            "--trajectories ({}) and --frames ({}) must be at least 1",
            o.trajectories,
            o.frames
        );
    }
    if !(o.fps.is_finite() && o.fps > 0.0) {
        bail!("--fps {} must be finite and > 0", o.fps);
    }
    if o.confidence_scenes == 0 {
        bail!("--confidence-scenes must be at least 1");
    }
    let (theta_min, theta_max) = o.theta_band;
    // Checks the band (and the rest) before the slow training.
    Trajectory::with_elevation(0, o.fps, DEFAULT_DISTANCE, theta_min, theta_max)
        .with_context(|| format!("--theta-min {theta_min} / --theta-max {theta_max}"))?;
    let start = Instant::now();
    let db = train(&object, config, o.confidence_scenes)?;
    let train_seconds = start.elapsed().as_secs_f64();
    let filter_config = FilterConfig::default();
    let intrinsics = Intrinsics::default();
    let probe = Pipeline::new(db.clone(), intrinsics.width, intrinsics.height, None)?;
    let conf_threshold = probe.confidence().map_or(0.0, |m| m.threshold());
    drop(probe);
    let grid = acch_seeding::grid_spacing(
        db.views()
            .iter()
            .map(|v| (v.theta_deg as f64, v.phi_deg as f64)),
    );
    let database_min_theta = db
        .views()
        .iter()
        .map(|v| v.theta_deg as f64)
        .fold(f64::INFINITY, f64::min);
    let ambiguity = view_ambiguity(&db);
    let episode_views = review_starts(o.episodes, o.seed)?;

    let mut rows = Vec::new();
    let mut review = Vec::new();
    for (b, (name, bg)) in BACKGROUNDS.into_iter().enumerate() {
        let background: Background = bg.parse()?;
        let work = (o.trajectories * o.frames) as u64;
        let bar = common::progress(work, &format!("fusion {name}"));
        let records: Vec<Vec<FrameRecord>> = (0..o.trajectories)
            .into_par_iter()
            .map_init(
                || pipeline(&db),
                |p, t| -> Result<Vec<FrameRecord>> {
                    let p = p.as_mut().map_err(|e| anyhow::anyhow!("{e:#}"))?;
                    run_trajectory(
                        p,
                        &object,
                        background,
                        o,
                        (b, t),
                        (grid, database_min_theta),
                        filter_config,
                        &bar,
                    )
                },
            )
            .collect::<Result<_>>()?;
        bar.finish_and_clear();
        rows.push(summarise(
            name,
            o.trajectories,
            &records,
            database_min_theta,
        ));

        for policy in [Policy::Sweep, Policy::Response] {
            let bar = common::progress(o.episodes as u64, &format!("{} {name}", policy.name()));
            let episodes: Vec<Episode> = episode_views
                .par_iter()
                .enumerate()
                .map_init(
                    || pipeline(&db),
                    |p, (i, v)| -> Result<Episode> {
                        let p = p.as_mut().map_err(|e| anyhow::anyhow!("{e:#}"))?;
                        let e =
                            run_episode(p, &object, background, o, b, i, *v, policy, &ambiguity);
                        bar.inc(1);
                        Ok(e)
                    },
                )
                .collect::<Result<_>>()?;
            bar.finish_and_clear();
            review.push(summarise_review(name, policy, &episodes));
        }
    }

    let report = SequenceReport {
        protocol: "sequence",
        object: object.name().to_owned(),
        trajectories: o.trajectories,
        frames_per_trajectory: o.frames,
        fps: o.fps,
        theta_min_deg: theta_min,
        theta_max_deg: theta_max,
        database_min_theta_deg: database_min_theta,
        episodes: o.episodes,
        max_moves: o.max_moves,
        seed: o.seed,
        filter: filter_config,
        confidence_threshold: conf_threshold,
        rows,
        review,
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

/// Table 2's database: paper grid on the plain background, recognition
/// model, confidence network of the default kind.
fn train(object: &Arc<Object>, config: &TrainConfig, scenes: usize) -> Result<ViewDatabase> {
    let training = model::RenderedTraining {
        views: PAPER_GRID.parse()?,
        background: Background::default(),
        distance: DEFAULT_DISTANCE,
        seed: 0,
    };
    let mut db = model::train_rendered(object, config, &training)?;
    let samples = model::confidence_samples(
        &db,
        object,
        scenes,
        model::CONFIDENCE_SEED_BASE,
        DEFAULT_DISTANCE,
    )?;
    model::train_confidence(&mut db, &samples, model::DEFAULT_CONFIDENCE_KIND, 0)?;
    Ok(db)
}

fn pipeline(db: &ViewDatabase) -> Result<Pipeline> {
    let k = Intrinsics::default();
    Pipeline::new(db.clone(), k.width, k.height, Some(DEFAULT_DISTANCE as f32))
}

/// Scene seed of item `i` on background `b`: disjoint from table 2's (which
/// uses the set seed itself and `frame_seed(seed, i)`).
fn scene_seed(seed: u64, b: usize, i: usize, salt: u64) -> u64 {
    common::frame_seed(seed ^ (salt << 32) ^ ((b as u64 + 1) << 48), i)
}

/// The seed input of a frame's accepted estimate.
fn seed_input(result: &FrameResult, grid: GridSpacing) -> Option<SeedInput> {
    if !result.accepted() {
        return None;
    }
    let (e, roi) = (result.estimate?, result.roi?);
    let k = Intrinsics::default();
    let input = SeedInput {
        theta_deg: (e.theta_deg as f64).clamp(0.0, 90.0),
        phi_deg: e.phi_deg as f64,
        roi_centre_px: DVec2::new(
            roi.x as f64 + (roi.width as f64 - 1.0) / 2.0,
            roi.y as f64 + (roi.height as f64 - 1.0) / 2.0,
        ),
        intrinsics: Pinhole {
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
        },
        distance: Distance::Known {
            value: DEFAULT_DISTANCE,
            sigma: DISTANCE_SIGMA,
        },
        confidence: result
            .rating
            .map_or(1.0, |r| r.confidence.clamp(0.0, 1.0) as f64),
        grid,
    };
    Some(input)
}

/// Feeds a frame's accepted estimate to the filter. An estimate whose θ is
/// censored by the database (on its lowest slice, where every lower view
/// lands too) gives φ only; a filter started from it has the slice's θ with
/// an unknown-θ variance, which the next uncensored estimate overrides.
/// Returns the outcome, `None` when no measurement could be built.
fn feed(filter: &mut ViewFilter, input: &SeedInput, lowest_theta: f64) -> Result<Option<Outcome>> {
    let Ok(m) = Measurement::from_estimate(input, &CovarianceModel::default()) else {
        return Ok(None);
    };
    if !theta_censored(input.theta_deg, lowest_theta) {
        return Ok(Some(filter.update(&m)?));
    }
    Ok(Some(filter.update(&m.without_theta(input))?))
}

fn errors(estimate: (f64, f64), truth: &ViewPose) -> (f64, f64) {
    (
        (estimate.0 - truth.theta_deg).abs(),
        phi_error(estimate.1 as f32, truth.phi_deg as f32) as f64,
    )
}

#[allow(clippy::too_many_arguments)]
fn run_trajectory(
    pipeline: &mut Pipeline,
    object: &Arc<Object>,
    background: Background,
    o: &SequenceOptions,
    (b, t): (usize, usize),
    (grid, lowest_theta): (GridSpacing, f64),
    filter_config: FilterConfig,
    bar: &ProgressBar,
) -> Result<Vec<FrameRecord>> {
    let scene = scene_seed(o.seed, b, t, 1);
    let renderer = common::renderer(object.clone(), background, scene);
    let (lo, hi) = o.theta_band;
    let trajectory = Trajectory::with_elevation(scene, o.fps, DEFAULT_DISTANCE, lo, hi)?;
    let mut filter = ViewFilter::new(filter_config)?;
    let mut out = Vec::with_capacity(o.frames);
    let mut frame_img = acch_capture::Rendered::default();
    for frame in trajectory.frames().take(o.frames) {
        renderer.render_into(&frame.view, scene.wrapping_add(frame.index), &mut frame_img);
        let (w, h) = frame_img.image.dimensions();
        let result = pipeline.process(frame_img.image.as_raw(), w, h);
        let mut rec = FrameRecord {
            theta_deg: frame.view.theta_deg,
            single: result
                .estimate
                .map(|e| errors((e.theta_deg as f64, e.phi_deg as f64), &frame.view)),
            accepted: result.accepted(),
            ..FrameRecord::default()
        };
        filter.predict(&frame.camera_motion)?;
        if let Some(input) = seed_input(&result, grid) {
            rec.censored = theta_censored(input.theta_deg, lowest_theta);
            rec.outcome = feed(&mut filter, &input, lowest_theta)?;
        }
        if let Some(s) = filter.state() {
            let (dt, dp) = errors((s.theta_deg, s.phi_deg), &frame.view);
            let c = s.view_covariance_deg2;
            rec.fused = Some((dt, dp, c[0][0].max(0.0).sqrt(), c[1][1].max(0.0).sqrt()));
        }
        out.push(rec);
        bar.inc(1);
    }
    Ok(out)
}

fn summarise(
    name: &str,
    trajectories: usize,
    records: &[Vec<FrameRecord>],
    database_min_theta: f64,
) -> SequenceRow {
    let all: Vec<&FrameRecord> = records.iter().flatten().collect();
    let ratio = |k: usize, n: usize| k as f64 / n.max(1) as f64;
    // Mean (|Δφ|, |Δθ|) of a set of (|Δθ|, |Δφ|).
    let mean = |v: &[(f64, f64)]| {
        let k = v.len().max(1) as f64;
        (
            v.iter().map(|x| x.1).sum::<f64>() / k,
            v.iter().map(|x| x.0).sum::<f64>() / k,
        )
    };
    let answer = |r: &FrameRecord| r.single.filter(|_| r.accepted);
    let fused_err = |r: &FrameRecord| r.fused.map(|f| (f.0, f.1));
    let single_fails = |r: &FrameRecord| answer(r).is_none_or(fails);
    let fused_fails = |r: &FrameRecord| fused_err(r).is_none_or(fails);
    // Failure rates of both outcomes over a subset of frames.
    let rates = |frames: &[&FrameRecord]| {
        (
            ratio(
                frames.iter().filter(|r| single_fails(r)).count(),
                frames.len(),
            ),
            ratio(
                frames.iter().filter(|r| fused_fails(r)).count(),
                frames.len(),
            ),
        )
    };
    let n = all.len();
    let answers: Vec<(f64, f64)> = all.iter().filter_map(|r| answer(r)).collect();
    let estimates: Vec<(f64, f64)> = all.iter().filter_map(|r| r.single).collect();
    let fused: Vec<(f64, f64, f64, f64)> = all.iter().filter_map(|r| r.fused).collect();
    let fused_errs: Vec<(f64, f64)> = all.iter().filter_map(|r| fused_err(r)).collect();
    let started: Vec<&FrameRecord> = all.iter().copied().filter(|r| r.fused.is_some()).collect();
    let below: Vec<&FrameRecord> = all
        .iter()
        .copied()
        .filter(|r| r.theta_deg < database_min_theta)
        .collect();
    let paired: Vec<((f64, f64), (f64, f64))> = all
        .iter()
        .filter_map(|r| Some((answer(r)?, fused_err(r)?)))
        .collect();
    let (paired_single, paired_fused): (Vec<_>, Vec<_>) = paired.iter().copied().unzip();
    let (s_phi, s_theta) = mean(&answers);
    let (r_phi, r_theta) = mean(&estimates);
    let (f_phi, f_theta) = mean(&fused_errs);
    let (ps_phi, ps_theta) = mean(&paired_single);
    let (pf_phi, pf_theta) = mean(&paired_fused);
    let (single_started, fused_started) = rates(&started);
    let (single_below, fused_below) = rates(&below);
    let within = fused
        .iter()
        .filter(|f| f.0 <= 2.0 * f.2 && f.1 <= 2.0 * f.3)
        .count();
    let count = |p: &dyn Fn(&FrameRecord) -> bool| all.iter().filter(|r| p(r)).count();
    let single_wrong = answers.iter().filter(|e| fails(**e)).count();
    let fused_wrong = fused_errs.iter().filter(|e| fails(**e)).count();
    let single_failed = |r: &FrameRecord| r.single.is_some_and(fails);
    SequenceRow {
        background: name.to_owned(),
        trajectories,
        frames: n,
        below_database_frames: below.len(),
        single_failure_rate: ratio(count(&single_fails), n),
        single_no_answer_rate: ratio(n - answers.len(), n),
        single_wrong_rate: ratio(single_wrong, n),
        single_answer_failure_rate: ratio(single_wrong, answers.len()),
        single_mean_phi_err_deg: s_phi,
        single_mean_theta_err_deg: s_theta,
        single_not_found: count(&|r| r.single.is_none()),
        single_rejected: count(&|r| r.single.is_some() && !r.accepted),
        raw_failure_rate: ratio(count(&|r| r.single.is_none_or(fails)), n),
        raw_mean_phi_err_deg: r_phi,
        raw_mean_theta_err_deg: r_theta,
        fused_failure_rate: ratio(count(&fused_fails), n),
        fused_no_answer_rate: ratio(n - fused.len(), n),
        fused_wrong_rate: ratio(fused_wrong, n),
        fused_answer_failure_rate: ratio(fused_wrong, fused.len()),
        fused_mean_phi_err_deg: f_phi,
        fused_mean_theta_err_deg: f_theta,
        started_frames: started.len(),
        single_failure_rate_started: single_started,
        fused_failure_rate_started: fused_started,
        single_failure_rate_below: single_below,
        fused_failure_rate_below: fused_below,
        paired_frames: paired.len(),
        paired_single_mean_phi_err_deg: ps_phi,
        paired_fused_mean_phi_err_deg: pf_phi,
        paired_single_mean_theta_err_deg: ps_theta,
        paired_fused_mean_theta_err_deg: pf_theta,
        fused_within_2sigma: ratio(within, fused.len()),
        fused_mean_sigma_phi_deg: fused.iter().map(|f| f.3).sum::<f64>()
            / fused.len().max(1) as f64,
        fused_updates: count(&|r| {
            matches!(
                r.outcome,
                Some(Outcome::Fused { .. } | Outcome::Initialised)
            )
        }),
        gated: count(&|r| matches!(r.outcome, Some(Outcome::Gated { .. }))),
        gated_failures: count(&|r| {
            matches!(r.outcome, Some(Outcome::Gated { .. })) && single_failed(r)
        }),
        fused_failures: count(&|r| {
            matches!(
                r.outcome,
                Some(Outcome::Fused { .. } | Outcome::Initialised)
            ) && single_failed(r)
        }),
        reinitialised: count(&|r| matches!(r.outcome, Some(Outcome::Reinitialised { .. }))),
        censored: count(&|r| r.accepted && r.censored),
        censored_unused: count(&|r| r.accepted && r.censored && r.outcome.is_none()),
    }
}

/// How the arm picks the next view after a rejection.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Policy {
    Sweep,
    Response,
}

impl Policy {
    fn name(self) -> &'static str {
        match self {
            Policy::Sweep => "sweep",
            Policy::Response => "response",
        }
    }
}

/// How an episode ended.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Episode {
    /// Accepted and right after this many moves.
    Success(usize),
    /// Accepted and wrong after this many moves.
    AcceptedWrong(usize),
    /// Still rejected after every allowed move.
    GaveUp,
}

/// Per database view: its best match value with any view that would count
/// as a failure (|Δθ| > 10° or |Δφ| > 20°) relative to its match with
/// itself. High values: the view is easily mistaken for a wrong one.
fn view_ambiguity(db: &ViewDatabase) -> Vec<f32> {
    let views = db.views();
    (0..views.len())
        .into_par_iter()
        .map_init(
            || vec![0f32; views.len()],
            |resp, i| {
                db.response_into(db.histogram(i), resp);
                let own = resp[i].max(f32::MIN_POSITIVE);
                let (ti, pi) = (views[i].theta_deg, views[i].phi_deg);
                let worst = views
                    .iter()
                    .zip(resp.iter())
                    .filter(|(v, _)| {
                        (v.theta_deg - ti).abs() > FAIL_THETA_DEG
                            || phi_error(v.phi_deg, pi) > FAIL_PHI_DEG
                    })
                    .map(|(_, r)| *r)
                    .fold(0f32, f32::max);
                worst / own
            },
        )
        .collect()
}

/// Lowest elevation of re-view starts: below the database's 45°, as for the
/// confidence network's training scenes (`model::CONFIDENCE_MIN_THETA_DEG`):
/// a robot's camera is not confined to the grid, and views the database does
/// not cover are the ones the network must reject.
const REVIEW_MIN_THETA_DEG: f64 = 20.0;

/// `n` re-view start poses, θ uniform in [REVIEW_MIN_THETA_DEG, 90], φ in
/// [0, 360), from `seed` (salted apart from table 2's poses).
fn review_starts(n: usize, seed: u64) -> Result<Vec<ViewPose>> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed ^ 0x7265_7669_6577);
    (0..n)
        .map(|_| {
            let theta = rng.random_range(REVIEW_MIN_THETA_DEG..=90.0);
            let phi = rng.random_range(0.0..360.0);
            Ok(ViewPose::new(theta, phi, DEFAULT_DISTANCE)?)
        })
        .collect()
}

/// The database view nearest to (θ, φ).
fn nearest_view(db: &ViewDatabase, theta: f64, phi: f64) -> usize {
    let mut best = (f64::INFINITY, 0);
    for (i, v) in db.views().iter().enumerate() {
        let d = (v.theta_deg as f64 - theta).powi(2)
            + (phi_error(v.phi_deg, phi as f32) as f64).powi(2);
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1
}

/// The next move (target elevation, azimuth turn) of `policy`, given the
/// rejected frame's result and the views tried so far, in the arm's own
/// azimuth (relative to the start, which is all the arm knows).
fn next_move(
    policy: Policy,
    move_index: usize,
    pipeline: &Pipeline,
    result: &FrameResult,
    current: (f64, f64),
    tried: &[(f64, f64)],
    ambiguity: &[f32],
) -> (f64, f64) {
    let sweep = (SWEEP_THETA[move_index % SWEEP_THETA.len()], SWEEP_PHI);
    if policy == Policy::Sweep || result.estimate.is_none() {
        return sweep;
    }
    let est = pipeline.estimator();
    let db = est.database();
    let top = est.top(HYPOTHESES);
    let best = top.first().map_or(0.0, |t| t.1);
    let hypotheses: Vec<f64> = top
        .iter()
        .filter(|(_, v)| *v >= HYPOTHESIS_SHARE * best)
        .map(|(i, _)| db.views()[*i].phi_deg as f64)
        .collect();
    let mut choice = (f64::INFINITY, sweep);
    for theta in CANDIDATE_THETA {
        for k in 1..12 {
            let dphi = 30.0 * k as f64;
            let dphi = if dphi > 180.0 { dphi - 360.0 } else { dphi };
            let score: f64 = hypotheses
                .iter()
                .map(|h| ambiguity[nearest_view(db, theta, h + dphi)] as f64)
                .sum::<f64>()
                / hypotheses.len() as f64;
            // Arm-relative target; views already tried teach nothing new.
            let target = (theta, current.1 + dphi);
            let revisit = tried.iter().any(|t| {
                (t.0 - target.0).abs() < 10.0
                    && phi_error(t.1 as f32, target.1 as f32) < FAIL_PHI_DEG
            });
            // Ties go to the shorter move.
            let cost = score
                + if revisit { 1.0 } else { 0.0 }
                + 1e-4 * (dphi.abs() + (theta - current.0).abs());
            if cost < choice.0 {
                choice = (cost, (theta, dphi));
            }
        }
    }
    choice.1
}

#[allow(clippy::too_many_arguments)]
fn run_episode(
    pipeline: &mut Pipeline,
    object: &Arc<Object>,
    background: Background,
    o: &SequenceOptions,
    b: usize,
    i: usize,
    start: ViewPose,
    policy: Policy,
    ambiguity: &[f32],
) -> Episode {
    let scene = scene_seed(o.seed, b, i, 2);
    let renderer: Renderer = common::renderer(object.clone(), background, scene);
    let mut view = start;
    // The arm's own record: absolute elevation, azimuth relative to the start.
    let mut arm = (start.theta_deg, 0.0);
    let mut tried = vec![arm];
    let mut img = acch_capture::Rendered::default();
    for moves in 0..=o.max_moves {
        renderer.render_into(&view, scene.wrapping_add(moves as u64), &mut img);
        let (w, h) = img.image.dimensions();
        let result = pipeline.process(img.image.as_raw(), w, h);
        if result.accepted() {
            let e = result.estimate.expect("accepted implies an estimate");
            return if fails(errors((e.theta_deg as f64, e.phi_deg as f64), &view)) {
                Episode::AcceptedWrong(moves)
            } else {
                Episode::Success(moves)
            };
        }
        if moves == o.max_moves {
            break;
        }
        let (theta, dphi) = next_move(policy, moves, pipeline, &result, arm, &tried, ambiguity);
        arm = (theta, arm.1 + dphi);
        tried.push(arm);
        view = ViewPose {
            theta_deg: theta,
            phi_deg: (view.phi_deg + dphi).rem_euclid(360.0),
            distance: view.distance,
        };
    }
    Episode::GaveUp
}

fn summarise_review(name: &str, policy: Policy, episodes: &[Episode]) -> ReviewRow {
    let initially_correct = episodes
        .iter()
        .filter(|e| **e == Episode::Success(0))
        .count();
    let initially_wrong = episodes
        .iter()
        .filter(|e| **e == Episode::AcceptedWrong(0))
        .count();
    let rejected: Vec<&Episode> = episodes
        .iter()
        .filter(|e| !matches!(e, Episode::Success(0) | Episode::AcceptedWrong(0)))
        .collect();
    let mut moves: Vec<usize> = rejected
        .iter()
        .filter_map(|e| match e {
            Episode::Success(m) => Some(*m),
            _ => None,
        })
        .collect();
    moves.sort_unstable();
    let median = match moves.len() {
        0 => 0.0,
        n if n % 2 == 1 => moves[n / 2] as f64,
        n => (moves[n / 2 - 1] + moves[n / 2]) as f64 / 2.0,
    };
    ReviewRow {
        background: name.to_owned(),
        policy: policy.name().to_owned(),
        episodes: episodes.len(),
        initially_rejected: rejected.len(),
        initially_correct,
        initially_wrong,
        success_rate: moves.len() as f64 / rejected.len().max(1) as f64,
        mean_moves: moves.iter().sum::<usize>() as f64 / moves.len().max(1) as f64,
        median_moves: median,
        max_moves: moves.last().copied().unwrap_or(0),
        accepted_wrong: rejected
            .iter()
            .filter(|e| matches!(e, Episode::AcceptedWrong(_)))
            .count(),
        gave_up: rejected.iter().filter(|e| **e == &Episode::GaveUp).count(),
    }
}

fn print_report(r: &SequenceReport) {
    println!(
        "sequence · {} · {} trajectories x {} frames at {} fps per background, θ in [{}, {}] (database from {}) · confidence threshold {}",
        r.object,
        r.trajectories,
        r.frames_per_trajectory,
        r.fps,
        r.theta_min_deg,
        r.theta_max_deg,
        r.database_min_theta_deg,
        r.confidence_threshold
    );
    println!(
        "{:<10} {:>5} {:>5} | {:>7} {:>7} {:>7} {:>8} {:>8} | {:>7} {:>7} {:>7} {:>8} {:>8} | {:>15} {:>15} | {:>5} {:>5} {:>5} {:>5}",
        "background",
        "n",
        "below",
        "fail",
        "no-ans",
        "wrong",
        "E(phi)",
        "E(theta)",
        "fail",
        "no-ans",
        "wrong",
        "E(phi)",
        "E(theta)",
        "fail started",
        "fail below",
        "in2σ",
        "gated",
        "g.bad",
        "reinit",
    );
    let pct = |x: f64| format!("{:.1}%", 100.0 * x);
    for x in &r.rows {
        println!(
            "{:<10} {:>5} {:>5} | {:>7} {:>7} {:>7} {:>7.2}° {:>7.2}° | {:>7} {:>7} {:>7} {:>7.2}° {:>7.2}° | {:>15} {:>15} | {:>5} {:>5} {:>5} {:>5}",
            x.background,
            x.frames,
            x.below_database_frames,
            pct(x.single_failure_rate),
            pct(x.single_no_answer_rate),
            pct(x.single_wrong_rate),
            x.single_mean_phi_err_deg,
            x.single_mean_theta_err_deg,
            pct(x.fused_failure_rate),
            pct(x.fused_no_answer_rate),
            pct(x.fused_wrong_rate),
            x.fused_mean_phi_err_deg,
            x.fused_mean_theta_err_deg,
            format!(
                "{} → {}",
                pct(x.single_failure_rate_started),
                pct(x.fused_failure_rate_started)
            ),
            format!(
                "{} → {}",
                pct(x.single_failure_rate_below),
                pct(x.fused_failure_rate_below)
            ),
            format!("{:.0}%", 100.0 * x.fused_within_2sigma),
            x.gated,
            x.gated_failures,
            x.reinitialised,
        );
    }
    println!(
        "left: single frames (the accepted estimate; fail = none or wrong, no-ans = not found or rejected, errors over accepted estimates); middle: fused pose after each frame (no-ans = before the first accepted estimate, errors over frames with a fused pose); right: single → fused failure rate from the filter's start on and over the frames below the database; gated = accepted estimates the filter rejected, g.bad = of those, single-frame failures"
    );
    println!(
        "{:<10} {:>8} {:>9} {:>11} {:>6} {:>19} {:>19}",
        "background",
        "rejected",
        "not found",
        "table2 fail",
        "paired",
        "paired E(phi) s→f",
        "paired E(theta) s→f"
    );
    for x in &r.rows {
        println!(
            "{:<10} {:>8} {:>9} {:>11} {:>6} {:>19} {:>19}",
            x.background,
            x.single_rejected,
            x.single_not_found,
            pct(x.raw_failure_rate),
            x.paired_frames,
            format!(
                "{:.2}° → {:.2}°",
                x.paired_single_mean_phi_err_deg, x.paired_fused_mean_phi_err_deg
            ),
            format!(
                "{:.2}° → {:.2}°",
                x.paired_single_mean_theta_err_deg, x.paired_fused_mean_theta_err_deg
            ),
        );
    }
    println!(
        "table2 fail: table 2's definition (every estimate, accepted or not, counts; not found fails); paired: frames with both an accepted estimate and a fused pose, and the mean errors over them"
    );
    println!(
        "re-view · {} episodes per background, at most {} moves",
        r.episodes, r.max_moves
    );
    println!(
        "{:<10} {:<9} {:>8} {:>9} {:>10} | {:>8} {:>6} {:>6} {:>4} {:>6} {:>7}",
        "background",
        "policy",
        "rejected",
        "0-move ok",
        "0-move bad",
        "success",
        "mean",
        "median",
        "max",
        "wrong",
        "gave up",
    );
    for x in &r.review {
        println!(
            "{:<10} {:<9} {:>8} {:>9} {:>10} | {:>7.1}% {:>6.2} {:>6.1} {:>4} {:>6} {:>7}",
            x.background,
            x.policy,
            x.initially_rejected,
            x.initially_correct,
            x.initially_wrong,
            100.0 * x.success_rate,
            x.mean_moves,
            x.median_moves,
            x.max_moves,
            x.accepted_wrong,
            x.gave_up,
        );
    }
    println!(
        "success, moves, wrong and gave up are over the episodes whose first view was rejected; wrong = ended on an accepted wrong estimate · training {:.1} s, total {:.1} s",
        r.train_seconds, r.total_seconds
    );
}
