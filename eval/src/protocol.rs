//! What every protocol shares: the paper's training grid, the test
//! backgrounds, the failure rule, how scenes are seeded and rendered, and
//! the chain every protocol runs.

use crate::EvalError;
use acch_capture::{Background, Object, Rendered, Renderer, SceneConfig, TextureSet, ViewPose};
use acch_confidence::Tolerance;
use acch_core::ViewDatabase;
use acch_pipeline::wire::{Intrinsics, Maybe};
use acch_pipeline::{Chain, FrameHeader, StageSettings};
use acch_pose::train::LabelledView;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use std::sync::Arc;

/// The paper's training grid: θ in {45, 50, 60, 70, 80, 90} x φ every 10°.
pub const PAPER_GRID: &str = "grid:45,50,60,70,80,90:10";

/// The paper's failure rule (section 3.1): an open-loop grasp fails beyond
/// |Δθ| > 10° or |Δφ| > 20°. The one home of the rule.
pub fn failure_rule() -> Tolerance {
    Tolerance::default()
}

/// The view of `db` nearest to (θ, φ), degrees: the least sum of the
/// squared differences in θ and in (wrapped) φ.
pub fn nearest_view(db: &ViewDatabase, (theta, phi): (f32, f32)) -> usize {
    let mut best = (f32::INFINITY, 0);
    for (i, v) in db.views().iter().enumerate() {
        let d = (v.theta_deg - theta).powi(2) + acch_pose::phi_error(v.phi_deg, phi).powi(2);
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1
}

/// Whether estimate (θ, φ) fails against the truth (θ, φ), degrees.
pub fn fails(estimate: (f32, f32), truth: (f32, f32)) -> bool {
    !failure_rule().reliable(estimate, truth)
}

/// Whether estimate (θ, φ, roll) fails against the truth, degrees, for a
/// camera that may roll: |Δθ| beyond the paper's 10°, or the whole camera
/// rotation ([`rotation_error_deg`]) further off than the paper's 20° of φ.
/// For an upright view a turn in φ is a rotation by as much, so this is
/// the paper's rule (a little stricter where θ and φ both err); near
/// θ = 90°, where φ alone is not defined, a turn in φ traded for a roll is
/// the same camera and does not fail, while a seed turned by a roll the
/// pose stage did not find (its roll is 0 without the search) does.
pub fn fails_with_roll(estimate: [f32; 3], truth: [f32; 3]) -> bool {
    let rule = failure_rule();
    let (e, t) = (estimate.map(f64::from), truth.map(f64::from));
    let theta_ok = (e[0] - t[0]).abs() <= rule.theta_deg as f64;
    !(theta_ok && rotation_error_deg(e, t) <= rule.phi_deg as f64)
}

/// Whether errors (|Δθ|, |Δφ|), degrees, fail the paper's rule.
pub fn errors_fail((dtheta, dphi): (f64, f64)) -> bool {
    let rule = failure_rule();
    dtheta > rule.theta_deg as f64 || dphi > rule.phi_deg as f64
}

/// (|Δθ|, |Δφ|) of `estimate` (θ, φ) against `truth`, degrees.
pub fn view_errors(estimate: (f64, f64), truth: &ViewPose) -> (f64, f64) {
    (
        (estimate.0 - truth.theta_deg).abs(),
        acch_pose::phi_error(estimate.1 as f32, truth.phi_deg as f32) as f64,
    )
}

/// The angle between two camera rotations given as (θ, φ, roll), degrees:
/// the error of the whole rotation, which near θ = 90° stays small when a
/// turn in φ is traded for a roll (the same rotation there). θ is clamped
/// into [0, 90] to build the rotation.
pub fn rotation_error_deg(estimate: [f64; 3], truth: [f64; 3]) -> f64 {
    camera_rotation(estimate)
        .angle_between(camera_rotation(truth))
        .to_degrees()
}

/// The camera rotation (world from camera) of (θ, φ, roll), degrees, θ
/// clamped into [0, 90].
fn camera_rotation([theta, phi, roll]: [f64; 3]) -> glam::DQuat {
    let v = ViewPose {
        theta_deg: theta.clamp(0.0, 90.0),
        phi_deg: phi,
        distance: 1.0,
        roll_deg: roll,
    };
    glam::DQuat::from_mat3(&v.world_from_camera_rotation())
}

/// How far the estimated camera is turned about its optical axis against
/// the truth, degrees: the twist about the viewing ray of the rotation
/// between them (its swing–twist decomposition). The roll angle alone is
/// a coordinate that trades against φ (at θ = 90° they are the same turn,
/// and at θ = 45° still seven tenths of one), so its error says little
/// near the top; this is the in-image turn a tracker seeded with the
/// estimate starts with, whatever mix of φ and roll makes it.
pub fn turn_error_deg(estimate: [f64; 3], truth: [f64; 3]) -> f64 {
    // In the estimated camera's frame, where the optical axis is z.
    let q = camera_rotation(estimate).inverse() * camera_rotation(truth);
    let twist = 2.0 * q.z.atan2(q.w).to_degrees();
    let d = twist.rem_euclid(360.0);
    d.min(360.0 - d)
}

/// The views rolled uniformly in ±`max_deg`, drawn from `seed`.
pub fn rolled(views: Vec<ViewPose>, max_deg: f64, seed: u64) -> Result<Vec<ViewPose>, EvalError> {
    if max_deg == 0.0 {
        return Ok(views);
    }
    let mut state = seed ^ 0x9e37_79b9_7f4a_7c15;
    views
        .into_iter()
        .map(|v| {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            let u = (state >> 11) as f64 / (1u64 << 53) as f64;
            Ok(v.with_roll((2.0 * u - 1.0) * max_deg)?)
        })
        .collect()
}

/// |a - b| of two rolls, wrapped, degrees.
pub fn roll_error_deg(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

/// Backgrounds of the textured-scene protocols: (reported name, renderer
/// background). `clutter` is reported for distractors painted in the
/// object's own colours.
pub const BACKGROUNDS: [(&str, &str); 4] = [
    ("A", "A"),
    ("B", "B"),
    ("C", "C"),
    ("clutter", "clutter-similar"),
];

/// The backgrounds of [`BACKGROUNDS`], parsed.
pub fn backgrounds() -> Vec<(&'static str, Background)> {
    BACKGROUNDS
        .iter()
        .map(|(name, bg)| (*name, bg.parse().expect("the protocol's backgrounds parse")))
        .collect()
}

/// Scene seed of item `i` on background `b` of protocol part `salt`:
/// disjoint from table 2's (which uses the set seed itself and
/// `frame_seed(seed, i)`).
pub fn scene_seed(seed: u64, b: usize, i: usize, salt: u64) -> u64 {
    acch_capture::frame_seed(seed ^ (salt << 32) ^ ((b as u64 + 1) << 48), i)
}

/// The `[FIRST] [OBJECTS] [N]` arguments of a diagnosis example: generated
/// objects FIRST.., OBJECTS of them, N poses a background (defaults 3000,
/// `objects`, `n`).
pub fn diagnosis_args(objects: u64, n: usize) -> Result<(u64, u64, usize), EvalError> {
    let args: Vec<u64> = std::env::args()
        .skip(1)
        .take(3)
        .map(|a| {
            a.parse()
                .map_err(|_| EvalError::Input(format!("'{a}': expected [FIRST] [OBJECTS] [N]")))
        })
        .collect::<Result<_, _>>()?;
    Ok((
        args.first().copied().unwrap_or(3000),
        args.get(1).copied().unwrap_or(objects),
        args.get(2).map_or(n, |&v| v as usize),
    ))
}

/// The scenes the diagnosis examples and their tests share for generated
/// object `k` on background `b` (0, 1, 2: A, B, C): the configuration
/// (held-out textures, to which the caller adds its perturbation), the
/// scene seed (one `salt` per diagnosis) and `n` random poses.
pub fn diagnosis_scenes(
    object: &Arc<Object>,
    k: u64,
    b: usize,
    salt: u64,
    n: usize,
) -> Result<(SceneConfig, u64, Vec<ViewPose>), EvalError> {
    let background: Background = ["A", "B", "C"][b].parse()?;
    let config = SceneConfig::new(object.clone(), background).with_textures(TextureSet::HeldOut);
    let seed = scene_seed(7_000 + k, b, 0, salt);
    let views = acch_capture::ViewSpec::Random { n }.views(acch_capture::DEFAULT_DISTANCE, seed);
    Ok((config, seed, views))
}

/// A progress bar on stderr with a message and a count.
pub fn progress(len: u64, message: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template("{msg:>12} [{bar:40}] {pos}/{len} {elapsed_precise}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_message(message.to_owned());
    bar
}

/// A renderer of `object` on `background` with the default intrinsics and
/// the table textures of `textures`.
pub fn renderer(
    object: Arc<Object>,
    background: Background,
    textures: TextureSet,
    scene_seed: u64,
) -> Renderer {
    Renderer::new(
        SceneConfig::new(object, background).with_textures(textures),
        scene_seed,
    )
}

/// Renders `views` in parallel, in order, with a progress bar; view `i`
/// gets frame seed `frame_seed(seed, i)`.
pub fn render_views(
    renderer: &Renderer,
    views: &[ViewPose],
    seed: u64,
    message: &str,
) -> Vec<Rendered> {
    let bar = progress(views.len() as u64, message);
    let out = views
        .par_iter()
        .enumerate()
        .map(|(i, v)| {
            let r = renderer.render(v, acch_capture::frame_seed(seed, i));
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    out
}

/// Renders each test pose on `background` in parallel, scene `i` with frame
/// seed `frame_seed(seed, i)`; with `out_of_view_px` also the same scene
/// with the principal point moved that far, the object out of view (an
/// empty scene). Clutter layouts change from image to image.
pub fn render_scenes(
    object: &Arc<Object>,
    (background, textures): (Background, TextureSet),
    views: &[ViewPose],
    seed: u64,
    name: &str,
    out_of_view_px: Option<f64>,
) -> Vec<(Rendered, Option<Rendered>)> {
    let bar = progress(views.len() as u64, &format!("background {name}"));
    let shared =
        (!background.has_clutter()).then(|| renderer(object.clone(), background, textures, seed));
    let out = views
        .par_iter()
        .enumerate()
        .map(|(i, v)| {
            let scene_seed = acch_capture::frame_seed(seed, i);
            let own;
            let scene = match &shared {
                Some(r) => r,
                None => {
                    own = renderer(object.clone(), background, textures, scene_seed);
                    &own
                }
            };
            let empty = out_of_view_px.map(|shift| {
                let mut far = acch_capture::Intrinsics::default();
                far.cx += shift;
                let empty = Renderer::new(
                    SceneConfig {
                        intrinsics: far,
                        ..scene.config().clone()
                    },
                    if shared.is_some() { seed } else { scene_seed },
                );
                empty.render(v, scene_seed)
            });
            let r = (scene.render(v, scene_seed), empty);
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    out
}

/// A rendered view as training input, with its ground-truth mask and
/// where the object centre projects.
pub fn labelled(r: &Rendered, train_distance: f64) -> LabelledView<'_> {
    let view = LabelledView::new(
        r.image.as_raw(),
        r.mask.as_raw(),
        r.image.dimensions(),
        (r.truth.theta_deg as f32, r.truth.phi_deg as f32),
        (train_distance / r.truth.distance) as f32,
    );
    match r.truth.object_centre_px() {
        Some(c) => view.with_centre([c.x as f32, c.y as f32]),
        None => view,
    }
}

/// The frame header of rendered frame `sequence` of an object of real
/// radius `radius_m`, with its ground truth in metres and, when `arm` is
/// set, the arm's camera pose (so seeding fuses over the camera's motion),
/// as the simulated camera sends it.
pub fn frame_of(r: &Rendered, sequence: u64, arm: bool, radius_m: f64) -> FrameHeader {
    let (w, h) = r.image.dimensions();
    let mut f = FrameHeader::rgb(sequence, w, h, Intrinsics::from(&r.truth.intrinsics));
    let (truth, pose) = acch_pipeline::source::metric_truth(&r.truth, radius_m);
    f.envelope.frame.truth = Maybe::Present(truth);
    if arm {
        f.envelope.frame.arm = Maybe::Present(pose);
    }
    f
}

/// Intersection over union of two masks (non-zero = set).
pub fn mask_iou(a: &[u8], b: &[u8]) -> f64 {
    let (mut inter, mut union) = (0u64, 0u64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (x != 0, y != 0);
        inter += (x && y) as u64;
        union += (x || y) as u64;
    }
    if union == 0 {
        0.0
    } else {
        inter as f64 / union as f64
    }
}

/// The chain of the deployed stages over `db`, for frames of the default
/// camera at the known training distance (as every protocol runs it).
pub fn chain(db: &ViewDatabase) -> Result<Chain, EvalError> {
    chain_at(db, db.train_distance_m as f64, 0)
}

/// [`chain`] for a camera `distance_m` metres from the object, trying
/// `light_search` lights per weak image.
pub fn chain_at(
    db: &ViewDatabase,
    distance_m: f64,
    light_search: usize,
) -> Result<Chain, EvalError> {
    chain_for_sets(db, None, distance_m, light_search)
}

/// [`chain_at`] for the sharp database `db` and, when given, the smoothed
/// one, chosen per frame by recognition (`--smoothing auto`).
pub fn chain_for_sets(
    db: &ViewDatabase,
    smoothed: Option<&ViewDatabase>,
    distance_m: f64,
    light_search: usize,
) -> Result<Chain, EvalError> {
    let settings = settings_at(db, distance_m, light_search);
    Ok(Chain::build_for_sets(db, smoothed, &settings)?)
}

/// The settings every protocol builds `db`'s stages with: the default
/// camera `distance_m` metres from the object, the roll search the
/// database was trained with, `light_search` lights per weak image.
pub fn settings_at(db: &ViewDatabase, distance_m: f64, light_search: usize) -> StageSettings {
    let k = acch_capture::Intrinsics::default();
    StageSettings {
        width: k.width,
        height: k.height,
        distance_m: Some(distance_m),
        unrated: false,
        roll_search_deg: acch_pose::trained_roll_search_deg(db),
        light_search,
        verify_shape: true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_view_wraps_in_phi_and_weighs_theta_and_phi_alike() {
        use acch_core::{ColourSpace, HistogramParams, Palette, View};
        let palette =
            Palette::from_centres(ColourSpace::Lab, vec![[50.0, 0.0, 0.0]], 10.0).expect("palette");
        let params = HistogramParams {
            colours: 1,
            bins: 2,
            ..HistogramParams::default()
        };
        let mut db = ViewDatabase::new("grid", palette, params, 1.0);
        let h = vec![1.0 / params.len() as f32; params.len()];
        for theta_deg in [45.0, 60.0, 90.0] {
            for phi_deg in [0.0, 90.0, 180.0, 270.0] {
                let view = View {
                    theta_deg,
                    phi_deg,
                    size_px: 100.0,
                    centre_offset_px: [0.0; 2],
                };
                db.push_view(view, &h);
            }
        }
        let at = |i: usize| (db.views()[i].theta_deg, db.views()[i].phi_deg);
        assert_eq!(at(nearest_view(&db, (50.0, 350.0))), (45.0, 0.0));
        assert_eq!(at(nearest_view(&db, (56.0, 100.0))), (60.0, 90.0));
        // 12° and 40° away (90°, 180°) before 18° and 40° (60°, 180°).
        assert_eq!(at(nearest_view(&db, (78.0, 220.0))), (90.0, 180.0));
    }

    #[test]
    fn the_rule_fails_beyond_ten_degrees_of_theta_or_twenty_of_phi() {
        assert!(!fails((60.0, 10.0), (70.0, 30.0)));
        assert!(fails((60.0, 10.0), (70.1, 10.0)));
        assert!(fails((60.0, 350.0), (60.0, 10.5)));
        assert!(!fails((60.0, 350.0), (60.0, 9.5)));
        assert!(fails((f32::NAN, 0.0), (60.0, 0.0)));
    }

    #[test]
    fn a_roll_beyond_the_phi_tolerance_fails() {
        assert!(!fails_with_roll([60.0, 10.0, 0.0], [60.0, 10.0, 19.0]));
        assert!(fails_with_roll([60.0, 10.0, 0.0], [60.0, 10.0, 21.0]));
        assert!(!fails_with_roll([60.0, 10.0, 175.0], [60.0, 10.0, -175.0]));
        assert!(fails_with_roll([60.0, 40.0, 0.0], [60.0, 10.0, 0.0]));
        assert!(fails_with_roll([60.0, 10.0, 0.0], [70.5, 10.0, 0.0]));
        assert!(fails_with_roll([f32::NAN, 10.0, 0.0], [60.0, 10.0, 0.0]));
    }

    #[test]
    fn upright_it_is_the_papers_rule_and_at_the_pole_phi_may_trade_for_roll() {
        for (e, t) in [((60.0, 10.0), (60.0, 29.0)), ((60.0, 10.0), (60.0, 31.0))] {
            assert_eq!(
                fails_with_roll([e.0, e.1, 0.0], [t.0, t.1, 0.0]),
                fails(e, t)
            );
        }
        // Looking straight down, φ off by 40° with the roll off by as much
        // is the right camera; the same φ error without the roll is not.
        assert!(!fails_with_roll([90.0, 70.0, 40.0], [90.0, 30.0, 0.0]));
        assert!(fails_with_roll([90.0, 70.0, 0.0], [90.0, 30.0, 0.0]));
    }

    #[test]
    fn a_turn_in_phi_traded_for_a_roll_is_the_same_rotation_only_at_the_pole() {
        // Looking straight down, φ + 20° with roll + 20° is the same camera.
        assert!(rotation_error_deg([90.0, 50.0, 20.0], [90.0, 30.0, 0.0]) < 1e-6);
        // At the horizon it is a 28° error.
        let e = rotation_error_deg([0.0, 50.0, 20.0], [0.0, 30.0, 0.0]);
        assert!((e - 28.2).abs() < 0.2, "{e}");
        assert!((rotation_error_deg([60.0, 10.0, 0.0], [60.0, 10.0, 15.0]) - 15.0).abs() < 1e-6);
    }

    #[test]
    fn the_turn_about_the_optical_axis_is_the_roll_error_and_ignores_the_trade() {
        let turn = turn_error_deg([60.0, 10.0, 15.0], [60.0, 10.0, 0.0]);
        assert!((turn - 15.0).abs() < 1e-6, "{turn}");
        assert!(turn_error_deg([90.0, 50.0, 20.0], [90.0, 30.0, 0.0]) < 1e-6);
        // A tilt in θ turns nothing about the viewing ray.
        assert!(turn_error_deg([70.0, 10.0, 0.0], [60.0, 10.0, 0.0]) < 1e-6);
        // At θ = 45° a turn in φ is in part one about the viewing ray.
        let turn = turn_error_deg([45.0, 30.0, 0.0], [45.0, 10.0, 0.0]);
        assert!(turn > 10.0 && turn < 20.0, "{turn}");
    }

    #[test]
    fn scene_seeds_of_parts_and_backgrounds_differ() {
        let s = [
            scene_seed(1, 0, 0, 1),
            scene_seed(1, 1, 0, 1),
            scene_seed(1, 0, 1, 1),
            scene_seed(1, 0, 0, 2),
        ];
        for i in 0..s.len() {
            for j in i + 1..s.len() {
                assert_ne!(s[i], s[j]);
            }
        }
    }
}
