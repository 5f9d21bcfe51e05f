//! Active re-view: a rejected view makes the arm move the camera and try
//! again, up to a number of moves; two policies choose the next view (see
//! [`crate::sequence`] for the protocol).

use crate::EvalError;
use crate::protocol::{self, errors_fail as fails, scene_seed, view_errors as errors};
use acch_capture::{Background, DEFAULT_DISTANCE, Object, Renderer, TextureSet, ViewPose};
use acch_core::ViewDatabase;
use acch_pipeline::Chain;
use acch_pose::phi_error;
use rayon::prelude::*;
use serde::Serialize;
use std::sync::Arc;

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

/// How the arm picks the next view after a rejection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Policy {
    /// A fixed schedule.
    Sweep,
    /// The most informative next view from the rejected frame's response.
    Response,
}

impl Policy {
    /// Its name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Policy::Sweep => "sweep",
            Policy::Response => "response",
        }
    }
}

/// How an episode ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Episode {
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
pub fn view_ambiguity(db: &ViewDatabase) -> Vec<f32> {
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
                    .filter(|(v, _)| protocol::fails((v.theta_deg, v.phi_deg), (ti, pi)))
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
pub fn review_starts(n: usize, seed: u64) -> Result<Vec<ViewPose>, EvalError> {
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

/// The next move (target elevation, azimuth turn) of `policy`, given the
/// rejected frame's result and the views tried so far, in the arm's own
/// azimuth (relative to the start, which is all the arm knows).
fn next_move(
    policy: Policy,
    move_index: usize,
    chain: &Chain,
    estimated: bool,
    current: (f64, f64),
    tried: &[(f64, f64)],
    ambiguity: &[f32],
) -> (f64, f64) {
    let sweep = (SWEEP_THETA[move_index % SWEEP_THETA.len()], SWEEP_PHI);
    if policy == Policy::Sweep || !estimated {
        return sweep;
    }
    let est = chain.stages().pose.last_used().estimator();
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
                .map(|h| {
                    ambiguity[protocol::nearest_view(db, (theta as f32, (h + dphi) as f32))] as f64
                })
                .sum::<f64>()
                / hypotheses.len() as f64;
            // Arm-relative target; views already tried teach nothing new.
            let target = (theta, current.1 + dphi);
            let revisit = tried.iter().any(|t| {
                (t.0 - target.0).abs() < 10.0
                    && phi_error(t.1 as f32, target.1 as f32) < protocol::failure_rule().phi_deg
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

/// Runs episode `i` on background `b` from `start`: the chain rates each
/// view; a rejection makes the arm move by `policy`, up to `max_moves`;
/// `seed` is the protocol's.
#[allow(clippy::too_many_arguments)]
pub fn run_episode(
    chain: &mut Chain,
    object: &Arc<Object>,
    background: Background,
    (seed, max_moves): (u64, usize),
    (b, i): (usize, usize),
    start: ViewPose,
    policy: Policy,
    ambiguity: &[f32],
) -> Episode {
    let scene = scene_seed(seed, b, i, 2);
    let renderer: Renderer =
        protocol::renderer(object.clone(), background, TextureSet::HeldOut, scene);
    let mut view = start;
    // The arm's own record: absolute elevation, azimuth relative to the start.
    let mut arm = (start.theta_deg, 0.0);
    let mut tried = vec![arm];
    let mut img = acch_capture::Rendered::default();
    for moves in 0..=max_moves {
        renderer.render_into(&view, scene.wrapping_add(moves as u64), &mut img);
        // One view at a time: no arm pose, nothing fused across views.
        let frame = protocol::frame_of(&img, moves as u64, false, object.radius_m());
        let result = chain.process(&frame, img.image.as_raw());
        if result.accepted()
            && let Some(e) = result.pose().done()
        {
            return if fails(errors((e.theta_deg as f64, e.phi_deg as f64), &view)) {
                Episode::AcceptedWrong(moves)
            } else {
                Episode::Success(moves)
            };
        }
        if moves == max_moves {
            break;
        }
        let estimated = result.pose().done().is_some();
        let (theta, dphi) = next_move(policy, moves, chain, estimated, arm, &tried, ambiguity);
        arm = (theta, arm.1 + dphi);
        tried.push(arm);
        view = ViewPose {
            theta_deg: theta,
            phi_deg: (view.phi_deg + dphi).rem_euclid(360.0),
            distance: view.distance,
            roll_deg: 0.0,
        };
    }
    Episode::GaveUp
}

/// The re-view row of `episodes` on background `name` with `policy`.
pub fn summarise_review(name: &str, policy: Policy, episodes: &[Episode]) -> ReviewRow {
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
