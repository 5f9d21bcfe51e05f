//! Temporal fusion and active re-view along camera trajectories, beyond the
//! paper (which proposes both in its conclusion): `acch eval --protocol
//! sequence`.
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
//! each frame carries the arm's camera pose, as the simulated camera sends
//! it, and the deployed seeding stage fuses every accepted estimate over
//! the arm's motion, exactly as `acch run` does (an estimate on the
//! database's lowest θ slice is censored: fused for φ only).
//!
//! Per frame, the single-frame outcome is the accepted estimate, a failure
//! when wrong (table 2's thresholds) or missing (not found, nothing
//! estimated, rejected by the confidence network: the robot has no pose);
//! the fused outcome is the filter's state after predict + update, a failure
//! when wrong or missing (frames before the first accepted estimate). Both
//! kinds of failure are reported apart (`*_no_answer_rate`, `*_wrong_rate`),
//! as are table 2's own figures over every estimate (`raw_*`).
//!
//! Active re-view ([`crate::review`]): per background, `n` episodes start at random poses with
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

use crate::protocol::{self, errors_fail as fails, scene_seed, view_errors as errors};
use crate::review::{
    Policy, ReviewRow, review_starts, run_episode, summarise_review, view_ambiguity,
};
use crate::{EvalError, write_json};
use acch_capture::{Background, DEFAULT_DISTANCE, Object, TextureSet, Trajectory};
use acch_core::ViewDatabase;
use acch_pipeline::stages::Fusion;
use acch_pipeline::stages::seeding::KNOWN_DISTANCE_RELATIVE_SIGMA;
use acch_pipeline::{Chain, Hop};
use acch_pose::train::TrainConfig;
use acch_seeding::{FilterConfig, theta_censored};
use acch_train::confidence::{self, ConfidenceScenes};
use acch_train::views::{RenderedTraining, train_rendered};
use indicatif::ProgressBar;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Options of the sequence protocol.
#[derive(Clone, Debug)]
pub struct SequenceOptions {
    /// Trajectories per background.
    pub trajectories: usize,
    /// Frames per trajectory.
    pub frames: usize,
    /// Frame rate of the trajectories (sets how far the arm moves per frame).
    pub fps: f64,
    /// How long the camera's shutter is open, seconds (at most a frame
    /// period): the camera moves along the trajectory meanwhile and each
    /// frame blurs along that motion; 0 = an instant.
    pub shutter_s: f64,
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

/// The sequence protocol's report.
#[derive(Serialize, Debug)]
pub struct SequenceReport {
    /// "sequence".
    pub protocol: &'static str,
    /// The object.
    pub object: String,
    /// Trajectories per background.
    pub trajectories: usize,
    /// Frames per trajectory.
    pub frames_per_trajectory: usize,
    /// Their frame rate.
    pub fps: f64,
    /// The camera's exposure, milliseconds (0: an instant).
    pub shutter_ms: f64,
    /// Lowest elevation of the trajectories, degrees.
    pub theta_min_deg: f64,
    /// Highest elevation of the trajectories, degrees.
    pub theta_max_deg: f64,
    /// The database's lowest θ slice, degrees.
    pub database_min_theta_deg: f64,
    /// Re-view episodes per background.
    pub episodes: usize,
    /// Moves allowed per episode.
    pub max_moves: usize,
    /// Seed of scenes, trajectories and episode poses.
    pub seed: u64,
    /// The deployed seeding stage's filter.
    pub filter: FilterConfig,
    /// The relative standard deviation of the known distance the deployed
    /// seeding stage hands each seed.
    pub distance_relative_sigma: f64,
    /// The confidence network's threshold.
    pub confidence_threshold: f32,
    /// Fusion results, one row per background.
    pub rows: Vec<SequenceRow>,
    /// Re-view results, one row per background and policy.
    pub review: Vec<ReviewRow>,
    /// Training time, s.
    pub train_seconds: f64,
    /// Time of the whole protocol, s.
    pub total_seconds: f64,
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
    outcome: Option<Fusion>,
}

/// Runs the sequence protocol for one object.
pub fn sequence(
    object: Arc<Object>,
    options: &SequenceOptions,
    config: &TrainConfig,
) -> Result<SequenceReport, EvalError> {
    let o = options;
    if o.trajectories == 0 || o.frames == 0 {
        return Err(EvalError::Input(format!(
            "--trajectories ({}) and --frames ({}) must be at least 1",
            o.trajectories, o.frames
        )));
    }
    if !(o.fps.is_finite() && o.fps > 0.0) {
        return Err(EvalError::Input(format!(
            "--fps {} must be finite and > 0",
            o.fps
        )));
    }
    if !(o.shutter_s.is_finite() && (0.0..=1.0 / o.fps).contains(&o.shutter_s)) {
        return Err(EvalError::Input(format!(
            "--shutter-ms {} must be 0 up to a frame period ({:.1} ms at --fps {})",
            o.shutter_s * 1000.0,
            1000.0 / o.fps,
            o.fps
        )));
    }
    if o.confidence_scenes == 0 {
        return Err(EvalError::Input(
            "--confidence-scenes must be at least 1".into(),
        ));
    }
    let (theta_min, theta_max) = o.theta_band;
    // Checks the band (and the rest) before the slow training.
    Trajectory::with_elevation(0, o.fps, DEFAULT_DISTANCE, theta_min, theta_max).map_err(|e| {
        EvalError::Input(format!(
            "--theta-min {theta_min} / --theta-max {theta_max}: {e}"
        ))
    })?;
    let start = Instant::now();
    let db = train(&object, config, o.confidence_scenes)?;
    let train_seconds = start.elapsed().as_secs_f64();
    let probe = protocol::chain(&db)?;
    let conf_threshold = probe.stages().confidence.sharp().threshold().unwrap_or(0.0);
    let filter_config = *probe.stages().seeding.filter_config();
    let database_min_theta = probe.stages().seeding.lowest_theta_deg();
    drop(probe);
    let ambiguity = view_ambiguity(&db);
    let episode_views = review_starts(o.episodes, o.seed)?;

    let mut rows = Vec::new();
    let mut review = Vec::new();
    for (b, (name, background)) in protocol::backgrounds().into_iter().enumerate() {
        let work = (o.trajectories * o.frames) as u64;
        let bar = protocol::progress(work, &format!("fusion {name}"));
        let records: Vec<Vec<FrameRecord>> = (0..o.trajectories)
            .into_par_iter()
            .map_init(
                || protocol::chain(&db),
                |chain, t| -> Result<Vec<FrameRecord>, EvalError> {
                    let chain = chain
                        .as_mut()
                        .map_err(|e| EvalError::Worker(e.to_string()))?;
                    run_trajectory(
                        chain,
                        &object,
                        background,
                        o,
                        (b, t),
                        database_min_theta,
                        &bar,
                    )
                },
            )
            .collect::<Result<_, _>>()?;
        bar.finish_and_clear();
        rows.push(summarise(
            name,
            o.trajectories,
            &records,
            database_min_theta,
        ));

        for policy in [Policy::Sweep, Policy::Response] {
            let bar = protocol::progress(o.episodes as u64, &format!("{} {name}", policy.name()));
            let episodes = episode_views
                .par_iter()
                .enumerate()
                .map_init(
                    || protocol::chain(&db),
                    |chain, (i, v)| -> Result<_, EvalError> {
                        let chain = chain
                            .as_mut()
                            .map_err(|e| EvalError::Worker(e.to_string()))?;
                        let e = run_episode(
                            chain,
                            &object,
                            background,
                            (o.seed, o.max_moves),
                            (b, i),
                            *v,
                            policy,
                            &ambiguity,
                        );
                        bar.inc(1);
                        Ok(e)
                    },
                )
                .collect::<Result<Vec<_>, _>>()?;
            bar.finish_and_clear();
            review.push(summarise_review(name, policy, &episodes));
        }
    }

    Ok(SequenceReport {
        protocol: "sequence",
        object: object.name().to_owned(),
        trajectories: o.trajectories,
        frames_per_trajectory: o.frames,
        fps: o.fps,
        shutter_ms: o.shutter_s * 1000.0,
        theta_min_deg: theta_min,
        theta_max_deg: theta_max,
        database_min_theta_deg: database_min_theta,
        episodes: o.episodes,
        max_moves: o.max_moves,
        seed: o.seed,
        filter: filter_config,
        distance_relative_sigma: KNOWN_DISTANCE_RELATIVE_SIGMA,
        confidence_threshold: conf_threshold,
        rows,
        review,
        train_seconds,
        total_seconds: start.elapsed().as_secs_f64(),
    })
}

impl SequenceReport {
    /// Writes the report as JSON.
    pub fn write_json(&self, path: &Path) -> Result<(), EvalError> {
        write_json(path, self)
    }
}

/// Table 2's database: paper grid on the plain background, recognition
/// model, confidence network of the input chosen on validation scenes.
fn train(
    object: &Arc<Object>,
    config: &TrainConfig,
    scenes: usize,
) -> Result<ViewDatabase, EvalError> {
    let mut db = train_rendered(object, config, &RenderedTraining::default())?;
    let (choice, model, _) = confidence::choose_confidence_input(
        &db,
        object,
        scenes,
        DEFAULT_DISTANCE,
        ConfidenceScenes::default(),
        0,
    )?;
    tracing::info!("{choice}");
    model.store(&mut db);
    Ok(db)
}

/// Runs one trajectory through the chain: every frame carries the arm's
/// camera pose, so the deployed seeding stage fuses over the motion.
fn run_trajectory(
    chain: &mut Chain,
    object: &Arc<Object>,
    background: Background,
    o: &SequenceOptions,
    (b, t): (usize, usize),
    lowest_theta: f64,
    bar: &ProgressBar,
) -> Result<Vec<FrameRecord>, EvalError> {
    let scene = scene_seed(o.seed, b, t, 1);
    let renderer = protocol::renderer(object.clone(), background, TextureSet::HeldOut, scene);
    let (lo, hi) = o.theta_band;
    let trajectory = Trajectory::with_elevation(scene, o.fps, DEFAULT_DISTANCE, lo, hi)?;
    // A new trajectory: nothing carries over from the last one.
    chain.stages_mut().seeding.reset();
    let mut out = Vec::with_capacity(o.frames);
    let mut img = acch_capture::Rendered::default();
    for frame in trajectory.frames().take(o.frames) {
        renderer.render_moving_into(
            trajectory.during(frame.index, o.shutter_s),
            scene.wrapping_add(frame.index),
            &mut img,
        );
        let result = chain.process(
            &protocol::frame_of(&img, frame.index, true, object.radius_m()),
            img.image.as_raw(),
        );
        let estimate = result.pose().done();
        let accepted = result.accepted();
        let mut rec = FrameRecord {
            theta_deg: frame.view.theta_deg,
            single: estimate.map(|e| errors((e.theta_deg as f64, e.phi_deg as f64), &frame.view)),
            accepted,
            censored: accepted
                && estimate.is_some_and(|e| {
                    theta_censored((e.theta_deg as f64).clamp(0.0, 90.0), lowest_theta)
                }),
            outcome: match result.seeding.fusion {
                Fusion::None => None,
                f => Some(f),
            },
            ..FrameRecord::default()
        };
        if let Some(s) = result.seeding.fused.get() {
            let (dt, dp) = errors((s.view_deg[0], s.view_deg[1]), &frame.view);
            let c = s.view_covariance_deg2;
            rec.fused = Some((dt, dp, c[0].max(0.0).sqrt(), c[3].max(0.0).sqrt()));
        }
        debug_assert_eq!(result.envelope().frame.sequence, frame.index);
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
        fused_updates: count(&|r| matches!(r.outcome, Some(Fusion::Fused | Fusion::Started))),
        gated: count(&|r| r.outcome == Some(Fusion::Gated)),
        gated_failures: count(&|r| r.outcome == Some(Fusion::Gated) && single_failed(r)),
        fused_failures: count(&|r| {
            matches!(r.outcome, Some(Fusion::Fused | Fusion::Started)) && single_failed(r)
        }),
        reinitialised: count(&|r| r.outcome == Some(Fusion::Restarted)),
        censored: count(&|r| r.accepted && r.censored),
        censored_unused: count(&|r| r.accepted && r.censored && r.outcome.is_none()),
    }
}

impl SequenceReport {
    /// Prints the tables.
    pub fn print(&self) {
        let r = self;
        println!(
            "sequence · {} · {} trajectories x {} frames at {} fps, shutter {} ms, per background, θ in [{}, {}] (database from {}) · confidence threshold {}",
            r.object,
            r.trajectories,
            r.frames_per_trajectory,
            r.fps,
            r.shutter_ms,
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
}
