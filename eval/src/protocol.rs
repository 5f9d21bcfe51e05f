//! What every protocol shares: the paper's training grid, the test
//! backgrounds, the failure rule, how scenes are seeded and rendered, and
//! the chain every protocol runs. The grid, the failure rule and the
//! rendering helpers training shares live in [`acch_train::scenes`] and
//! are reached from here too.

use crate::EvalError;
use acch_capture::{Background, Object, Rendered, Renderer, SceneConfig, TextureSet, ViewPose};
use acch_core::ViewDatabase;
use acch_pipeline::{Chain, StageSettings};
use rayon::prelude::*;
use std::sync::Arc;

pub use acch_train::scenes::{
    PAPER_GRID, fails, fails_with_roll, failure_rule, frame_of, labelled, progress, render_views,
    renderer, rotation_error_deg, turn_error_deg,
};

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
