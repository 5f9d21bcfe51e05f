//! Beyond the paper: a camera that rolls about its optical axis. The
//! database is trained for it (`acch train --roll-search-deg`: the pose
//! stage searches the roll, the confidence network learns on the responses
//! of that search over rolled scenes), and the deployed chain runs on the
//! same random poses twice, upright and rolled uniformly within ±the roll,
//! on textured backgrounds with recognition and segmentation finding the
//! object. The failure rule is the whole rotation's
//! ([`protocol::fails_with_roll`]): near θ = 90° φ alone is not defined
//! once the camera rolls. With `compare`, the default database (no search,
//! an upright network) runs on the same scenes beside it.

use crate::protocol::{self, fails_with_roll};
use crate::{EvalError, write_json};
use acch_capture::{DEFAULT_DISTANCE, Object, Rendered, TextureSet, ViewSpec};
use acch_core::ViewDatabase;
use acch_pipeline::Hop;
use acch_pipeline::wire::StageId;
use acch_pose::train::TrainConfig;
use acch_train::confidence::{ConfidenceChoice, ConfidenceInput, ConfidenceScenes, train_object};
use acch_train::views::RenderedTraining;
use serde::Serialize;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Options of the roll protocol.
#[derive(Clone, Copy, Debug)]
pub struct RollOptions {
    /// Random test poses per background.
    pub n: usize,
    /// Seed of the test poses, their rolls and the scenes.
    pub seed: u64,
    /// The test views' roll, uniform in ±this, degrees.
    pub roll_deg: f64,
    /// The roll the database is trained to search, degrees.
    pub search_deg: f64,
    /// Confidence-training scenes per background.
    pub confidence_scenes: usize,
    /// Also run the default database (no search, upright network).
    pub compare: bool,
}

/// One row: one database on one background, upright or rolled views.
#[derive(Clone, Debug, Serialize)]
pub struct RollRow {
    /// Which database: "roll-trained" or "default".
    pub database: String,
    /// Background name.
    pub background: String,
    /// The views' roll range, degrees (0: upright).
    pub roll_deg: f64,
    /// Test images.
    pub n: usize,
    /// Images in which the object was not found.
    pub not_found: usize,
    /// Share of failures ([`protocol::fails_with_roll`], or not found).
    pub failure_rate: f64,
    /// Share failing the paper's rule on (θ, φ) alone, or not found (what
    /// the paper would count; near θ = 90° it counts right rotations as
    /// wrong once the camera rolls).
    pub paper_failure_rate: f64,
    /// Share of images whose estimate the confidence network accepted.
    pub accepted_rate: f64,
    /// Failure rate among the accepted.
    pub acc_failure_rate: f64,
    /// Share of the accepted whose whole rotation is within 10° of the
    /// truth.
    pub acc_rot10_rate: f64,
    /// Mean turn of the estimated camera about its optical axis against the
    /// truth over the estimates ([`protocol::turn_error_deg`]), degrees:
    /// the roll error that means something at every θ.
    pub mean_turn_err_deg: f64,
    /// Mean |Δroll| of the roll angle over the estimates, degrees (near
    /// θ = 90° it trades against φ).
    pub mean_roll_err_deg: f64,
    /// Mean |Δroll| over the estimates with θ at most 80° (where roll and
    /// φ are told apart), degrees.
    pub mean_roll_err_below_80_deg: f64,
    /// Mean whole-rotation error over the estimates, degrees.
    pub mean_rotation_err_deg: f64,
    /// Mean time of the pose stage, ms.
    pub ms_pose: f64,
}

/// The roll protocol's report.
#[derive(Serialize, Debug)]
pub struct RollReport {
    /// "roll".
    pub protocol: &'static str,
    /// The object.
    pub object: String,
    /// Test poses per background.
    pub n: usize,
    /// Seed of the test poses and scenes.
    pub seed: u64,
    /// The rolled views' range, degrees.
    pub roll_deg: f64,
    /// The search the database was trained with, degrees.
    pub search_deg: f64,
    /// The confidence input chosen for the roll-trained database.
    pub confidence_choice: Option<ConfidenceChoice>,
    /// The rows.
    pub rows: Vec<RollRow>,
    /// Time of the trainings, s.
    pub train_seconds: f64,
    /// Time of the whole protocol, s.
    pub total_seconds: f64,
}

/// Runs the roll protocol for `object`.
pub fn roll(
    object: Arc<Object>,
    options: &RollOptions,
    config: &TrainConfig,
) -> Result<RollReport, EvalError> {
    let o = *options;
    if o.n == 0 {
        return Err(EvalError::Input("--n must be at least 1".into()));
    }
    for (name, deg) in [
        ("--roll-deg", o.roll_deg),
        ("--roll-search-deg", o.search_deg),
    ] {
        if !(deg.is_finite() && (0.0..=180.0).contains(&deg)) {
            return Err(EvalError::Input(format!(
                "{name} {deg} must be a finite number of degrees in [0, 180]"
            )));
        }
    }
    let start = Instant::now();
    let trained = |scenes: ConfidenceScenes| {
        let training = RenderedTraining {
            scenes,
            ..RenderedTraining::default()
        };
        let confidence = Some((o.confidence_scenes.max(1), ConfidenceInput::Auto));
        train_object(&object, config, &training, confidence)
    };
    let (rolled_db, choice) = trained(ConfidenceScenes {
        roll_deg: o.search_deg,
        search_deg: o.search_deg,
        ..ConfidenceScenes::default()
    })?;
    let mut databases = vec![("roll-trained", rolled_db)];
    if o.compare {
        databases.push(("default", trained(ConfidenceScenes::default())?.0));
    }
    let train_seconds = start.elapsed().as_secs_f64();

    let upright = ViewSpec::Random { n: o.n }.views(DEFAULT_DISTANCE, o.seed);
    let rolled = protocol::rolled(upright.clone(), o.roll_deg, o.seed)?;
    let mut rows = Vec::new();
    for (name, background) in protocol::backgrounds() {
        let scenes = |views, label: &str| {
            protocol::render_scenes(
                &object,
                (background, TextureSet::HeldOut),
                views,
                o.seed,
                &format!("{name} {label}"),
                None,
            )
        };
        // The same scene seeds: a rolled scene is its upright one, turned.
        let sets = [
            (0.0, scenes(&upright, "upright")),
            (o.roll_deg, scenes(&rolled, "rolled")),
        ];
        for (db_name, db) in &databases {
            for (roll_deg, set) in &sets {
                let row = measure(db, set, object.radius_m())?;
                rows.push(RollRow {
                    database: (*db_name).to_owned(),
                    background: name.to_owned(),
                    roll_deg: *roll_deg,
                    ..row
                });
            }
        }
    }
    Ok(RollReport {
        protocol: "roll",
        object: object.name().to_owned(),
        n: o.n,
        seed: o.seed,
        roll_deg: o.roll_deg,
        search_deg: o.search_deg,
        confidence_choice: choice,
        rows,
        train_seconds,
        total_seconds: start.elapsed().as_secs_f64(),
    })
}

/// The chain of `db` (with the search it was trained with) over `scenes`;
/// the row's names are left for the caller.
fn measure(
    db: &ViewDatabase,
    scenes: &[(Rendered, Option<Rendered>)],
    radius_m: f64,
) -> Result<RollRow, EvalError> {
    let mut chain = protocol::chain(db)?;
    let (mut not_found, mut failures, mut paper_failures) = (0usize, 0usize, 0usize);
    let (mut accepted, mut acc_failures, mut acc_rot10) = (0usize, 0usize, 0usize);
    let (mut estimated, mut sum_roll, mut sum_rot, mut sum_turn) = (0usize, 0f64, 0f64, 0f64);
    let (mut below_80, mut sum_roll_below_80) = (0usize, 0f64);
    let mut ns_pose = 0u64;
    for (i, (scene, _)) in scenes.iter().enumerate() {
        let out = chain.process(
            &protocol::frame_of(scene, i as u64, false, radius_m),
            scene.image.as_raw(),
        );
        ns_pose += out.envelope().trail.process_ns(StageId::Pose);
        let t = &scene.truth;
        let truth = [t.theta_deg, t.phi_deg, t.roll_deg];
        let Some(e) = out.pose().done() else {
            not_found += 1;
            failures += 1;
            paper_failures += 1;
            continue;
        };
        let estimate = [e.theta_deg as f64, e.phi_deg as f64, e.roll_deg as f64];
        let failed = fails_with_roll(
            [e.theta_deg, e.phi_deg, e.roll_deg],
            truth.map(|x| x as f32),
        );
        failures += failed as usize;
        paper_failures += protocol::fails(
            (e.theta_deg, e.phi_deg),
            (t.theta_deg as f32, t.phi_deg as f32),
        ) as usize;
        let roll_err = protocol::roll_error_deg(estimate[2], truth[2]);
        let rotation_err = protocol::rotation_error_deg(estimate, truth);
        estimated += 1;
        sum_roll += roll_err;
        sum_rot += rotation_err;
        sum_turn += protocol::turn_error_deg(estimate, truth);
        if e.theta_deg <= 80.0 {
            below_80 += 1;
            sum_roll_below_80 += roll_err;
        }
        if out.rating().verdict().is_some_and(|v| v.accepted) {
            accepted += 1;
            acc_failures += failed as usize;
            acc_rot10 += (rotation_err <= 10.0) as usize;
        }
    }
    let n = scenes.len();
    let share = |k: usize, of: usize| k as f64 / of.max(1) as f64;
    Ok(RollRow {
        database: String::new(),
        background: String::new(),
        roll_deg: 0.0,
        n,
        not_found,
        failure_rate: share(failures, n),
        paper_failure_rate: share(paper_failures, n),
        accepted_rate: share(accepted, n),
        acc_failure_rate: share(acc_failures, accepted),
        acc_rot10_rate: share(acc_rot10, accepted),
        mean_turn_err_deg: sum_turn / estimated.max(1) as f64,
        mean_roll_err_deg: sum_roll / estimated.max(1) as f64,
        mean_roll_err_below_80_deg: sum_roll_below_80 / below_80.max(1) as f64,
        mean_rotation_err_deg: sum_rot / estimated.max(1) as f64,
        ms_pose: ns_pose as f64 / 1e6 / n.max(1) as f64,
    })
}

impl RollReport {
    /// Writes the report as JSON.
    pub fn write_json(&self, path: &Path) -> Result<(), EvalError> {
        write_json(path, self)
    }

    /// Prints the table.
    pub fn print(&self) {
        println!(
            "roll protocol: {}, {} poses per background, seed {}, views upright and rolled within ±{}°, database trained to search ±{}°",
            self.object, self.n, self.seed, self.roll_deg, self.search_deg
        );
        if let Some(c) = &self.confidence_choice {
            println!("{c}");
        }
        println!(
            "{:<13} {:<8} {:>5} {:>4} {:>6} {:>6} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>6} {:>6}",
            "database",
            "bg",
            "roll",
            "lost",
            "fail",
            "paper",
            "accept",
            "accfail",
            "acc<10",
            "E(turn)",
            "E(roll)",
            "E(r)<80",
            "E(rot)",
            "ms"
        );
        for r in &self.rows {
            println!(
                "{:<13} {:<8} {:>5.0} {:>4} {:>5.1}% {:>5.1}% {:>6.1}% {:>6.1}% {:>6.1}% {:>6.2}° {:>6.2}° {:>6.2}° {:>5.2}° {:>6.2}",
                r.database,
                r.background,
                r.roll_deg,
                r.not_found,
                100.0 * r.failure_rate,
                100.0 * r.paper_failure_rate,
                100.0 * r.accepted_rate,
                100.0 * r.acc_failure_rate,
                100.0 * r.acc_rot10_rate,
                r.mean_turn_err_deg,
                r.mean_roll_err_deg,
                r.mean_roll_err_below_80_deg,
                r.mean_rotation_err_deg,
                r.ms_pose
            );
        }
        println!(
            "fail: the whole rotation more than 20° or θ more than 10° off, or not found; paper: the paper's rule on (θ, φ); acc<10: accepted within 10° of the truth; E(turn): the estimate's turn about the optical axis against the truth; E(roll): of the roll angle, which trades against φ near θ = 90°; E(r)<80: roll error where θ ≤ 80°. Trained in {:.0} s, all in {:.0} s",
            self.train_seconds, self.total_seconds
        );
    }
}
