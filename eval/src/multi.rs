//! Several known objects at once. Each scene holds `in_view` of the known
//! objects, touching and partly hiding each other, among distractors, on
//! backgrounds A, B and C; the [`MultiChain`] of every known object runs on
//! it, and, for comparison, each object's chain alone on the same scenes.
//!
//! Per background and object: detection recall (over the object's
//! appearances at most half hidden and not cut by the border), precision
//! (over every detection of its chain: a detection is right when the
//! object is the known object most seen in the window), segmentation IoU,
//! the failure rate (wrong object, wrong pose or not found, over the
//! counted appearances), the accepted rate, and failures among accepted
//! (every accepted estimate, a detection of the wrong thing included).
//! Confusions: detections of one object made on another.

use crate::protocol::{self, fails_with_roll};
use crate::{EvalError, write_json};
use acch_capture::{
    Background, MULTI_DISTANCE, MultiRendered, MultiRenderer, MultiScene, Object, ObjectTruth,
    SceneLight, TextureSet,
};
use acch_core::ViewDatabase;
use acch_pipeline::stages::RegionPayload;
use acch_pipeline::wire::{Intrinsics, PixelRect};
use acch_pipeline::{Chain, FrameHeader, MultiChain, Seeded};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

pub use acch_train::cache::OFF_AXIS_ROLL_SEARCH_DEG;

/// Camera elevations of the scenes, degrees: above the database's lowest
/// training elevation, below the pole.
pub const THETA_RANGE: (f64, f64) = (50.0, 85.0);

/// An appearance counts towards recall when at most this share of the
/// object is hidden by its neighbours.
pub const MAX_HIDDEN: f64 = 0.5;

/// ... and at least this many of its pixels are seen.
pub const MIN_VISIBLE_PX: u32 = 400;

/// A detection claims the known object most seen in its window, if that
/// object covers at least this share of the window; else the background.
const CLAIM_SHARE: f64 = 0.1;

/// Scene seeds of this protocol (see [`protocol::scene_seed`]).
const SALT: u64 = 0x6d75;

/// The backgrounds of the protocol.
const BACKGROUNDS: [(&str, Background); 3] = [
    ("A", Background::A),
    ("B", Background::B),
    ("C", Background::C),
];

/// What the multi-object protocol measures.
#[derive(Clone, Debug)]
pub struct MultiOptions {
    /// Scenes per background.
    pub n: usize,
    /// Seed of the scenes (layouts, views, which objects are in view).
    pub seed: u64,
    /// Known objects in each scene.
    pub in_view: usize,
    /// Unknown objects around them.
    pub distractors: usize,
    /// Where the light comes from.
    pub light: SceneLight,
}

impl MultiOptions {
    /// Refuses options that cannot measure anything with `known` objects.
    pub fn check(&self, known: usize) -> Result<(), EvalError> {
        if known == 0 || known > acch_capture::MAX_SCENE_OBJECTS {
            return Err(EvalError::Input(format!(
                "--objects: 1 to {} objects, not {known}",
                acch_capture::MAX_SCENE_OBJECTS
            )));
        }
        if self.in_view == 0 || self.in_view > known {
            return Err(EvalError::Input(format!(
                "--in-view {}: between 1 and the {known} objects known",
                self.in_view
            )));
        }
        if self.n == 0 {
            return Err(EvalError::Input("--n: at least one scene".into()));
        }
        Ok(())
    }
}

/// One object's figures on one background.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Figures {
    /// Appearances counted for recall.
    pub in_view: usize,
    /// Share of them detected (the object itself under the window).
    pub recall: f64,
    /// Share of the chain's detections that were the object.
    pub precision: f64,
    /// Mean IoU of the segmented region with the object's visible mask,
    /// over its right detections among the counted appearances.
    pub iou: f64,
    /// Wrong object, wrong pose or not found, over the counted appearances.
    pub failure_rate: f64,
    /// Right and accepted, over the counted appearances.
    pub accepted_rate: f64,
    /// Wrong among every accepted estimate of the chain.
    pub acc_failure_rate: f64,
    /// The chain's detections.
    pub detections: usize,
    /// Its accepted estimates.
    pub accepted: usize,
    /// Mean |Δφ| over right detections' estimates, degrees.
    pub mean_phi_err_deg: f64,
    /// Mean |Δθ| over them, degrees.
    pub mean_theta_err_deg: f64,
}

/// One row: an object on a background, with the others known and alone.
#[derive(Clone, Debug, Serialize)]
pub struct MultiRow {
    /// A, B or C.
    pub background: String,
    /// The object.
    pub object: String,
    /// With every object known.
    #[serde(flatten)]
    pub multi: Figures,
    /// Frames whose detection was withdrawn for another object's.
    pub suppressed: usize,
    /// The object's chain alone on the same scenes.
    pub single: Figures,
}

/// Detections of one object made on another.
#[derive(Clone, Debug, Serialize)]
pub struct Confusion {
    /// A, B or C.
    pub background: String,
    /// The chain that detected.
    pub detected_as: String,
    /// The object under its window.
    pub truth: String,
    /// How often, with every object known.
    pub count: usize,
}

/// The protocol's result.
#[derive(Clone, Debug, Serialize)]
pub struct MultiReport {
    /// The known objects.
    pub objects: Vec<String>,
    /// Scenes per background.
    pub n: usize,
    /// Known objects per scene.
    pub in_view: usize,
    /// Distractors per scene.
    pub distractors: usize,
    /// The scene seed.
    pub seed: u64,
    /// "as-trained" or "world".
    pub light: &'static str,
    /// Per background and object.
    pub rows: Vec<MultiRow>,
    /// Between objects.
    pub confusions: Vec<Confusion>,
    /// Every chain's judgement of every object in every scene, for
    /// [`MultiReport::write_errors`].
    #[serde(skip)]
    judged: Vec<(usize, usize, usize, &'static str, Judged)>,
}

/// Counts of one object on one background.
#[derive(Clone, Copy, Debug, Default)]
struct Tally {
    in_view: usize,
    found: usize,
    failures: usize,
    right_accepted: usize,
    detections: usize,
    right_detections: usize,
    accepted: usize,
    acc_failures: usize,
    iou: f64,
    estimated: usize,
    phi: f64,
    theta: f64,
}

impl Tally {
    fn figures(&self) -> Figures {
        let share = |a: usize, b: usize| if b == 0 { 0.0 } else { a as f64 / b as f64 };
        let mean = |s: f64, n: usize| if n == 0 { 0.0 } else { s / n as f64 };
        Figures {
            in_view: self.in_view,
            recall: share(self.found, self.in_view),
            precision: share(self.right_detections, self.detections),
            iou: mean(self.iou, self.found),
            failure_rate: share(self.failures, self.in_view),
            accepted_rate: share(self.right_accepted, self.in_view),
            acc_failure_rate: share(self.acc_failures, self.accepted),
            detections: self.detections,
            accepted: self.accepted,
            mean_phi_err_deg: mean(self.phi, self.estimated),
            mean_theta_err_deg: mean(self.theta, self.estimated),
        }
    }
}

/// What one chain made of one object in one scene.
#[derive(Clone, Copy, Debug, Default)]
struct Judged {
    /// Counted towards recall.
    counted: bool,
    /// It detected something: Some(Some(j)) known object j (scene order),
    /// Some(None) the background.
    claim: Option<Option<usize>>,
    /// The detection is the object itself.
    right: bool,
    /// Its region against the object's mask (right detections).
    iou: f64,
    /// (|Δθ|, |Δφ|) and whether the pose fails, for right estimates.
    pose: Option<(f64, f64, bool)>,
    accepted: bool,
    /// The object's view (θ, φ, roll) and hidden share, when in the scene.
    truth: Option<([f64; 3], f64)>,
    /// The estimate (θ, φ, roll), when one was made.
    estimate: Option<[f32; 3]>,
    /// The detection's score over its threshold, when one was made.
    margin: Option<f32>,
    /// The best view's match value, when estimated.
    match_value: Option<f32>,
    /// The verdict's confidence and rival, when rated.
    rating: Option<(f32, f32)>,
}

/// Which known object (scene index) covers the most of `window`, if one
/// covers at least [`CLAIM_SHARE`] of it.
fn claim(frame: &MultiRendered, window: &PixelRect) -> Option<usize> {
    let (w, h) = frame.labels.dimensions();
    let mut counts = [0usize; acch_capture::MAX_SCENE_OBJECTS + 1];
    for y in window.y..(window.y + window.height).min(h) {
        for x in window.x..(window.x + window.width).min(w) {
            counts[frame.labels.get_pixel(x, y).0[0] as usize] += 1;
        }
    }
    let (label, &most) = counts.iter().enumerate().skip(1).max_by_key(|(_, c)| **c)?;
    let area = window.width as f64 * window.height as f64;
    (most > 0 && most as f64 >= CLAIM_SHARE * area).then_some(label - 1)
}

/// Judges `out`, the result of the chain of the object at scene index
/// `own` (None: not in the scene), whose region is `region`.
fn judge(
    out: &Seeded,
    region: Option<RegionPayload<'_>>,
    frame: &MultiRendered,
    own: Option<&ObjectTruth>,
) -> Judged {
    let counted = own.is_some_and(|t| {
        t.hidden() <= MAX_HIDDEN && !t.at_border && t.visible_px >= MIN_VISIBLE_PX
    });
    let mut j = Judged {
        counted,
        accepted: out.accepted(),
        truth: own.map(|t| {
            (
                [t.view.theta_deg, t.view.phi_deg, t.view.roll_deg],
                t.hidden(),
            )
        }),
        estimate: out
            .pose()
            .done()
            .map(|e| [e.theta_deg, e.phi_deg, e.roll_deg]),
        match_value: out.pose().done().map(|e| e.best_value),
        rating: out.rating().verdict().map(|v| (v.confidence, v.rival)),
        ..Judged::default()
    };
    let Some(window) = out.detection().done() else {
        return j;
    };
    j.margin = Some(window.margin());
    let c = claim(frame, &window.window);
    j.claim = Some(c);
    let Some(truth) = own.filter(|t| c == Some(t.object)) else {
        return j;
    };
    j.right = true;
    if let Some(region) = region {
        let (w, h) = frame.labels.dimensions();
        let mut mask = Vec::new();
        region.frame_mask(w, h, &mut mask);
        j.iou = protocol::mask_iou(&mask, frame.mask(truth.object).as_raw());
    }
    if let Some(e) = out.pose().done() {
        let v = &truth.view;
        let estimate = [e.theta_deg, e.phi_deg, e.roll_deg];
        let t = [v.theta_deg as f32, v.phi_deg as f32, v.roll_deg as f32];
        j.pose = Some((
            (e.theta_deg as f64 - v.theta_deg).abs(),
            acch_pose::phi_error(e.phi_deg, v.phi_deg as f32) as f64,
            fails_with_roll(estimate, t),
        ));
    }
    j
}

impl Tally {
    fn add(&mut self, j: &Judged) {
        let pose_ok = j.right && j.pose.is_some_and(|p| !p.2);
        if j.counted {
            self.in_view += 1;
            self.found += j.right as usize;
            self.failures += !pose_ok as usize;
            self.right_accepted += (pose_ok && j.accepted) as usize;
            if j.right {
                self.iou += j.iou;
            }
        }
        if j.claim.is_some() {
            self.detections += 1;
            self.right_detections += j.right as usize;
        }
        if j.accepted {
            self.accepted += 1;
            self.acc_failures += !pose_ok as usize;
        }
        if let Some((dtheta, dphi, _)) = j.pose {
            self.estimated += 1;
            self.theta += dtheta;
            self.phi += dphi;
        }
    }
}

/// One scene's judgements: per known object, with every object known and
/// alone; and the lanes' withdrawn detections.
struct SceneResult {
    background: usize,
    scene: usize,
    multi: Vec<Judged>,
    single: Vec<Judged>,
    suppressed: Vec<bool>,
    /// (detecting object, object under the window), known indices.
    confusions: Vec<(usize, usize)>,
}

/// Runs the protocol: `objects` known, `databases[k]` that of `objects[k]`.
pub fn multi(
    objects: &[Arc<Object>],
    databases: &[ViewDatabase],
    options: &MultiOptions,
) -> Result<MultiReport, EvalError> {
    options.check(objects.len())?;
    let settings: Vec<_> = objects
        .iter()
        .zip(databases)
        .map(|(o, db)| protocol::settings_at(db, MULTI_DISTANCE * o.radius_m(), 0))
        .collect();
    let lanes: Vec<_> = databases.iter().zip(settings.iter().copied()).collect();
    // Fail early, on the caller's thread, if a database cannot run.
    MultiChain::build(&lanes, 1)?;
    let scenes: Vec<(usize, usize)> = (0..BACKGROUNDS.len())
        .flat_map(|b| (0..options.n).map(move |i| (b, i)))
        .collect();
    let bar = protocol::progress(scenes.len() as u64, "scenes");
    let chunk = scenes.len().div_ceil(rayon::current_num_threads().max(1));
    let results = scenes
        .par_chunks(chunk.max(1))
        .map(|part| {
            let mut multi = MultiChain::build(&lanes, 1)?;
            let mut singles = lanes
                .iter()
                .map(|(db, s)| Chain::build(db, s))
                .collect::<Result<Vec<_>, _>>()?;
            part.iter()
                .map(|&(b, i)| {
                    let r = scene(objects, options, (b, i), &mut multi, &mut singles);
                    bar.inc(1);
                    r
                })
                .collect::<Result<Vec<_>, EvalError>>()
        })
        .collect::<Result<Vec<_>, EvalError>>()?;
    bar.finish_and_clear();
    let k = objects.len();
    let mut multi_t = vec![vec![Tally::default(); k]; BACKGROUNDS.len()];
    let mut single_t = multi_t.clone();
    let mut suppressed = vec![vec![0usize; k]; BACKGROUNDS.len()];
    let mut confusions: BTreeMap<(usize, usize, usize), usize> = BTreeMap::new();
    for r in results.iter().flatten() {
        for o in 0..k {
            multi_t[r.background][o].add(&r.multi[o]);
            single_t[r.background][o].add(&r.single[o]);
            suppressed[r.background][o] += r.suppressed[o] as usize;
        }
        for &(a, t) in &r.confusions {
            *confusions.entry((r.background, a, t)).or_default() += 1;
        }
    }
    let judged = results
        .iter()
        .flatten()
        .flat_map(|r| {
            let both = r.multi.iter().map(|j| ("multi", j)).enumerate();
            let alone = r.single.iter().map(|j| ("alone", j)).enumerate();
            both.chain(alone)
                .map(move |(o, (mode, j))| (r.background, r.scene, o, mode, *j))
        })
        .collect();
    let name = |o: usize| objects[o].name().to_owned();
    let rows = (0..BACKGROUNDS.len())
        .flat_map(|b| (0..k).map(move |o| (b, o)))
        .map(|(b, o)| MultiRow {
            background: BACKGROUNDS[b].0.into(),
            object: name(o),
            multi: multi_t[b][o].figures(),
            suppressed: suppressed[b][o],
            single: single_t[b][o].figures(),
        })
        .collect();
    Ok(MultiReport {
        objects: (0..k).map(name).collect(),
        n: options.n,
        in_view: options.in_view,
        distractors: options.distractors,
        seed: options.seed,
        light: match options.light {
            SceneLight::AsTrained => "as-trained",
            SceneLight::World => "world",
        },
        rows,
        confusions: confusions
            .into_iter()
            .map(|((b, a, t), count)| Confusion {
                background: BACKGROUNDS[b].0.into(),
                detected_as: name(a),
                truth: name(t),
                count,
            })
            .collect(),
        judged,
    })
}

/// Renders scene `i` of background `b` and judges every chain on it.
fn scene(
    objects: &[Arc<Object>],
    options: &MultiOptions,
    (b, i): (usize, usize),
    multi: &mut MultiChain,
    singles: &mut [Chain],
) -> Result<SceneResult, EvalError> {
    let seed = protocol::scene_seed(options.seed, b, i, SALT);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    // Which known objects stand in the scene: a partial shuffle.
    let mut order: Vec<usize> = (0..objects.len()).collect();
    for s in 0..options.in_view {
        let pick = rng.random_range(s..order.len());
        order.swap(s, pick);
    }
    let present = &order[..options.in_view];
    let theta = rng.random_range(THETA_RANGE.0..=THETA_RANGE.1);
    let phi = rng.random_range(0.0..360.0);
    let mut scene = MultiScene::new(
        present.iter().map(|&o| objects[o].clone()).collect(),
        BACKGROUNDS[b].1,
    );
    scene.distractors = options.distractors;
    scene.textures = TextureSet::HeldOut;
    scene.light = options.light;
    let renderer = MultiRenderer::new(scene, seed).map_err(|e| EvalError::Input(e.to_string()))?;
    let frame = renderer.render(theta, phi, seed)?;
    let (w, h) = frame.image.dimensions();
    let k = Intrinsics::from(&renderer.scene().intrinsics);
    let header = FrameHeader::rgb(i as u64, w, h, k);
    // Scene index of each known object, if it stands in the scene.
    let at = |o: usize| present.iter().position(|&p| p == o);
    let truth = |o: usize| at(o).map(|s| &frame.objects[s]);
    let before: Vec<u64> = multi.lanes().iter().map(|l| l.suppressed).collect();
    let outs = multi.process(&header, frame.image.as_raw()).to_vec();
    let mut result = SceneResult {
        background: b,
        scene: i,
        multi: Vec::with_capacity(objects.len()),
        single: Vec::with_capacity(objects.len()),
        suppressed: Vec::with_capacity(objects.len()),
        confusions: Vec::new(),
    };
    for (o, (lane, out)) in multi.lanes().iter().zip(&outs).enumerate() {
        let j = judge(out, lane.chain.last_region(), &frame, truth(o));
        if let Some(Some(s)) = j.claim
            && !j.right
        {
            result.confusions.push((o, present[s]));
        }
        result.multi.push(j);
        result.suppressed.push(lane.suppressed > before[o]);
    }
    for (o, chain) in singles.iter_mut().enumerate() {
        let out = chain.process(&header, frame.image.as_raw());
        result
            .single
            .push(judge(&out, chain.last_region(), &frame, truth(o)));
    }
    Ok(result)
}

impl MultiReport {
    /// Writes the report as JSON.
    pub fn write_json(&self, path: &Path) -> Result<(), EvalError> {
        write_json(path, self)
    }

    /// Writes every chain's judgement of every known object in every scene
    /// as CSV (`mode`: multi, every object known; alone, its chain alone):
    /// the truth (view and hidden share; empty when the object was not in
    /// the scene), the estimate, whether the detection was the object,
    /// accepted, and whether the pose failed the rule.
    pub fn write_errors(&self, path: &Path) -> Result<(), EvalError> {
        use std::fmt::Write as _;
        let mut s = String::from(
            "background,scene,object,mode,in_scene,counted,detected,right,accepted,theta_deg,phi_deg,roll_deg,hidden,est_theta_deg,est_phi_deg,est_roll_deg,pose_fails,score_margin,match_value,confidence,rival\n",
        );
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.3}"));
        let opt32 = |v: Option<f32>| opt(v.map(f64::from));
        for (b, scene, o, mode, j) in &self.judged {
            let t = j.truth.map(|t| t.0);
            let e = j.estimate;
            let _ = writeln!(
                s,
                "{},{scene},{},{mode},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                BACKGROUNDS[*b].0,
                self.objects[*o],
                j.truth.is_some() as u8,
                j.counted as u8,
                j.claim.is_some() as u8,
                j.right as u8,
                j.accepted as u8,
                opt(t.map(|t| t[0])),
                opt(t.map(|t| t[1])),
                opt(t.map(|t| t[2])),
                opt(j.truth.map(|t| t.1)),
                opt(e.map(|e| e[0] as f64)),
                opt(e.map(|e| e[1] as f64)),
                opt(e.map(|e| e[2] as f64)),
                j.pose.map_or(String::new(), |p| (p.2 as u8).to_string()),
                opt32(j.margin),
                opt32(j.match_value),
                opt32(j.rating.map(|r| r.0)),
                opt32(j.rating.map(|r| r.1)),
            );
        }
        std::fs::write(path, s).map_err(|source| EvalError::Io {
            path: path.to_owned(),
            source,
        })
    }

    /// Prints the table.
    pub fn print(&self) {
        println!(
            "multi: {} known ({}), {} in view, {} distractors, {} scenes per background, seed {}, light {}",
            self.objects.len(),
            self.objects.join(", "),
            self.in_view,
            self.distractors,
            self.n,
            self.seed,
            self.light
        );
        println!(
            "{:<4} {:<22} {:>5} {:>7} {:>7} {:>5} {:>7} {:>7} {:>8} {:>5} | {:>7} {:>7} {:>8}",
            "bg",
            "object",
            "n",
            "recall",
            "prec",
            "iou",
            "fail",
            "acc",
            "acc-fail",
            "supp",
            "recall1",
            "prec1",
            "acc-fail1"
        );
        let pct = |v: f64| format!("{:.1}%", 100.0 * v);
        for r in &self.rows {
            let (m, s) = (&r.multi, &r.single);
            println!(
                "{:<4} {:<22} {:>5} {:>7} {:>7} {:>5.2} {:>7} {:>7} {:>8} {:>5} | {:>7} {:>7} {:>8}",
                r.background,
                r.object,
                m.in_view,
                pct(m.recall),
                pct(m.precision),
                m.iou,
                pct(m.failure_rate),
                pct(m.accepted_rate),
                pct(m.acc_failure_rate),
                r.suppressed,
                pct(s.recall),
                pct(s.precision),
                pct(s.acc_failure_rate)
            );
        }
        for c in &self.confusions {
            println!(
                "confusion on {}: {} detected on {} {} times",
                c.background, c.detected_as, c.truth, c.count
            );
        }
        println!(
            "left: every object known; right of |: the object's chain alone on the same scenes. n = appearances at most {:.0}% hidden, not at the border; fail = wrong object, wrong pose or not found; acc = right and accepted; acc-fail = wrong among accepted; supp = detections withdrawn for another object's",
            100.0 * MAX_HIDDEN
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_that_measure_nothing_are_refused() {
        let ok = MultiOptions {
            n: 2,
            seed: 1,
            in_view: 2,
            distractors: 2,
            light: SceneLight::AsTrained,
        };
        assert!(ok.check(3).is_ok());
        assert!(ok.check(1).is_err());
        assert!(
            MultiOptions {
                in_view: 0,
                ..ok.clone()
            }
            .check(3)
            .is_err()
        );
        assert!(MultiOptions { n: 0, ..ok.clone() }.check(3).is_err());
        assert!(ok.check(acch_capture::MAX_SCENE_OBJECTS + 1).is_err());
    }

    #[test]
    fn a_window_claims_the_object_most_seen_in_it() {
        let mut f = MultiRendered {
            labels: image::GrayImage::new(100, 100),
            ..MultiRendered::default()
        };
        for y in 0..50 {
            for x in 0..100 {
                f.labels
                    .put_pixel(x, y, image::Luma([if x < 60 { 1 } else { 2 }]));
            }
        }
        let rect = |x, y, s| PixelRect {
            x,
            y,
            width: s,
            height: s,
        };
        assert_eq!(claim(&f, &rect(0, 0, 40)), Some(0));
        assert_eq!(claim(&f, &rect(60, 0, 40)), Some(1));
        // Mostly table, and the object under a tenth: the background.
        assert_eq!(claim(&f, &rect(0, 46, 50)), None);
        assert_eq!(claim(&f, &rect(0, 60, 40)), None);
    }
}
