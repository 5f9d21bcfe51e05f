//! The light the camera sees the object under. An exposure change or a
//! colour cast multiplies each linear channel ([`acch_core::light`]), and
//! a palette learnt under the training light then maps most object pixels
//! to "not object" (at 0.6x brightness no fruitbox was found in 30
//! scenes). [`LightSearch`] relights the palette ([`Palette::relit`]) for
//! a grid of exposures and colour temperatures and, when the object is
//! weak or lost under the light in use, quantises the frame under the
//! neighbouring lights and keeps the one recognition scores best: the
//! light that makes the frame look most like the object's training views.
//! A single image's light is then chosen again among it and its
//! neighbours by a rating its caller gives ([`LightSearch::choose_light`];
//! the pipeline rates how much of the object's region a training view
//! explains).

use crate::{Detection, Detector};
use acch_core::light::{TRAINING_LIGHT_K, colour_temperature_gains};
use acch_core::{IndexView, NOT_OBJECT, Palette, Smoothing};
use std::collections::{BTreeMap, HashMap};
use std::hash::{Hash, Hasher};
use std::sync::{Arc, Mutex, OnceLock};

/// The exposures searched, linear multiples of the training light:
/// 2^(k/4) for k in -8..=6, 0.25 to 2.83 (about 0.55x to 1.55x in sRGB
/// bytes), each 1.19x its neighbour (1.08x in bytes).
pub const EXPOSURES: [f32; 15] = [
    0.25, 0.297, 0.354, 0.42, 0.5, 0.595, 0.707, 0.841, 1.0, 1.189, 1.414, 1.682, 2.0, 2.378, 2.828,
];

/// The colour temperatures searched, kelvin (the training light is
/// 5000 K): tungsten-warm to overcast-cool.
pub const COLOUR_TEMPERATURES_K: [f32; 7] = [
    3000.0,
    3500.0,
    4200.0,
    TRAINING_LIGHT_K,
    5800.0,
    6500.0,
    7500.0,
];

/// Below this share of the model's training score a detection is weak and
/// other lights are tried. Recognition's threshold is half the training
/// score; a frame under the training light scores near the training
/// score.
pub const WEAK_SCORE_FRACTION: f32 = 0.8;

/// Neighbours of a light: the other exposures and the other colour
/// temperatures.
pub const CANDIDATES: usize = EXPOSURES.len() + COLOUR_TEMPERATURES_K.len() - 2;

/// The share of the model's training score a detection under a light
/// other than the training light must reach (under the training light
/// 0.7x the model's threshold, 0.35 of the training score, is enough:
/// [`crate::MIN_FOUND_MARGIN`]). Relit, a
/// background can take on the object's colours: on table 2's scenes with
/// the object out of view the best window under any light reached 0.45 of
/// the training score (can, clutter), against 0.04 under the training
/// light alone. It was 0.7: an object seen from above (a bottle's cap)
/// scores little more than the threshold even under the right light, and
/// was lost under any other light (docs/accuracy.md, "Seen from above
/// under another light"); at 0.6 table 2 with the search still finds
/// nothing with the object out of view.
pub const RELIT_SCORE_FRACTION: f32 = 0.6;

/// Index of the training light in each grid.
const TRAINING: (usize, usize) = (8, 3);

/// The palette under the lights searched (built when first tried), and
/// the light in use.
#[derive(Clone, Debug)]
pub struct LightSearch {
    base: Palette,
    /// Identifies `base` in the process's shared relit palettes.
    fingerprint: u64,
    /// (exposure, colour temperature) grid indices -> palette relit so.
    lights: BTreeMap<(usize, usize), Arc<Palette>>,
    current: (usize, usize),
    /// Lights tried per weak frame besides the current one.
    per_frame: usize,
    /// Where the next weak frame's tries start in its candidate list (a
    /// frame with a small budget goes on where the last one stopped).
    offset: usize,
    /// A frame's indices under a light being rated
    /// ([`LightSearch::choose_light`]).
    scratch: Vec<u8>,
    /// Share of the training score a detection under another light must
    /// reach ([`RELIT_SCORE_FRACTION`]).
    relit_fraction: f32,
    /// The frame in hand is already blurred at least as much as the
    /// palette smooths: it is quantised as it is
    /// ([`LightSearch::set_frame_blurred`]).
    frame_blurred: bool,
}

impl LightSearch {
    /// The search over `palette`, trying `per_frame` other lights in a
    /// frame whose object is weak or lost under the current one (0: never,
    /// the training light only; [`CANDIDATES`] or more: every neighbour,
    /// and again around the best, as single images need).
    pub fn new(palette: &Palette, per_frame: usize) -> Self {
        let mut lights = BTreeMap::new();
        lights.insert(TRAINING, Arc::new(palette.clone()));
        LightSearch {
            base: palette.clone(),
            fingerprint: fingerprint(palette),
            lights,
            current: TRAINING,
            per_frame,
            offset: 0,
            scratch: Vec::new(),
            relit_fraction: RELIT_SCORE_FRACTION,
            frame_blurred: false,
        }
    }

    /// Says whether the frames to come are already blurred at least as
    /// much as the palette smooths (an object measured blurred, sent to a
    /// smoothing palette for it). Such a frame is quantised as it is:
    /// smoothed again it would be blurrier than the views the palette's
    /// database was trained on (blur 2 px on three development seeds:
    /// docs/accuracy.md, "A blurred frame is not smoothed again"). A
    /// palette that does not smooth quantises alike either way.
    pub fn set_frame_blurred(&mut self, blurred: bool) {
        self.frame_blurred = blurred;
    }

    /// Counts a detection under another light from `fraction` of the
    /// training score instead of [`RELIT_SCORE_FRACTION`] (the evaluations
    /// compare the two).
    pub fn set_relit_score_fraction(&mut self, fraction: f32) {
        self.relit_fraction = fraction;
    }

    /// The linear gains of the light in use ([1, 1, 1] is the training
    /// light).
    pub fn gains(&self) -> [f32; 3] {
        gains(self.current)
    }

    /// The palette of light `at`, relit on first use (by this process:
    /// searches of one palette share what another already built).
    fn palette(&mut self, at: (usize, usize)) -> &Palette {
        let (base, fingerprint) = (&self.base, self.fingerprint);
        self.lights
            .entry(at)
            .or_insert_with(|| shared_relit(base, fingerprint, at))
    }

    /// Neighbour `k` (0..[`CANDIDATES`]) of the light in use: the other
    /// exposures at its colour temperature, nearest first, then the other
    /// colour temperatures at its exposure (computed, not listed: the
    /// search allocates nothing per frame).
    fn candidate(&self, k: usize) -> (usize, usize) {
        let (e, t) = self.current;
        let others = EXPOSURES.len() - 1;
        if k < others {
            (nth_nearest(EXPOSURES.len(), e, k), t)
        } else {
            (e, nth_nearest(COLOUR_TEMPERATURES_K.len(), t, k - others))
        }
    }

    /// Quantises `rgb` into `indices` under the current light and detects;
    /// when the object is lost or weak, tries other lights within the
    /// frame's budget and keeps the best scoring: its indices are left in
    /// `indices`, the detector holds its counts, and it is the light of
    /// the next frame. With `quantised`, `indices` already hold the frame
    /// quantised under the training light (by a [`acch_core::JointPalette`]
    /// shared with other objects), and are used when that is the light in
    /// use.
    pub fn detect(
        &mut self,
        detector: &mut Detector,
        rgb: &[u8],
        (width, height): (u32, u32),
        (indices, quantised): (&mut [u8], bool),
        scale: Option<f32>,
    ) -> Option<Detection> {
        let train_score = detector.model().train_score;
        let relit_fraction = self.relit_fraction;
        // Indices written by another palette were smoothed as it smooths.
        let mut training_indices_ready = quantised && !self.frame_blurred;
        let frame_blurred = self.frame_blurred;
        let mut run =
            |at: (usize, usize), palette: &Palette, detector: &mut Detector, indices: &mut [u8]| {
                // Only the first run may find the indices written.
                let ready = std::mem::take(&mut training_indices_ready);
                if !(ready && at == TRAINING) {
                    quantise_frame(palette, frame_blurred, rgb, (width, height), indices);
                }
                let view = IndexView::new(width, height, indices).expect("sized by the caller");
                let found = detector
                    .detect(view, scale)
                    .filter(|d| counts(at, d, train_score, relit_fraction));
                (found, detector.best_score())
            };
        if self.per_frame >= CANDIDATES {
            // Single images: each searched afresh from the training light,
            // whatever came before.
            (self.current, self.offset) = (TRAINING, 0);
        }
        let current = self.current;
        let (found, score) = run(current, self.palette(current), detector, indices);
        if (found.is_some() && score >= WEAK_SCORE_FRACTION * train_score) || self.per_frame == 0 {
            return found;
        }
        // The best light is the best scoring one whose detection counts.
        let rank = |found: &Option<Detection>, score: f32| (found.is_some(), score);
        let (mut best, mut best_rank, mut best_found) = (current, rank(&found, score), found);
        let mut last = current;
        // A budget that covers every neighbour (as single images need)
        // gets two rounds: exposure and colour around the light in use,
        // then around the best of those.
        let rounds = if self.per_frame >= CANDIDATES { 2 } else { 1 };
        for _ in 0..rounds {
            let budget = self.per_frame.min(CANDIDATES);
            for i in 0..budget {
                let at = self.candidate((self.offset + i) % CANDIDATES);
                let (found, s) = run(at, self.palette(at), detector, indices);
                last = at;
                let r = rank(&found, s);
                if r > best_rank {
                    (best, best_rank, best_found) = (at, r, found);
                }
            }
            self.offset = if budget < CANDIDATES {
                self.offset + budget
            } else {
                0
            };
            if best == self.current {
                break;
            }
            self.current = best;
        }
        self.current = best;
        if last == best {
            // The detector and the indices hold the best light's frame.
            return best_found;
        }
        run(best, self.palette(best), detector, indices).0
    }

    /// Chooses again, among the light in use and its neighbours (every
    /// other exposure and colour temperature), the one under which `rate`
    /// rates the frame's indices best (how much of the object's region a
    /// training view explains, say: recognition's score picks lights that
    /// make the frame look like the object somewhere, not like one view
    /// of it). `indices` hold the frame under the light in use, where
    /// [`detect`](Self::detect) found `found`. When another light wins and
    /// recognition still counts the object under it, that light becomes
    /// the light in use, its indices are left in `indices`, the detector
    /// holds its counts and its detection is returned; otherwise all
    /// stays as it was.
    pub fn choose_light(
        &mut self,
        detector: &mut Detector,
        rgb: &[u8],
        (width, height): (u32, u32),
        (indices, found): (&mut [u8], Detection),
        scale: Option<f32>,
        mut rate: impl FnMut(&[u8]) -> Option<f32>,
    ) -> Option<Detection> {
        let in_use = self.current;
        let mut best = (in_use, rate(indices).unwrap_or(f32::MIN));
        let mut scratch = std::mem::take(&mut self.scratch);
        scratch.resize(indices.len(), NOT_OBJECT);
        for k in 0..CANDIDATES {
            let at = self.candidate(k);
            let blurred = self.frame_blurred;
            quantise_frame(
                self.palette(at),
                blurred,
                rgb,
                (width, height),
                &mut scratch,
            );
            if let Some(v) = rate(&scratch)
                && v > best.1
            {
                best = (at, v);
            }
        }
        self.scratch = scratch;
        if best.0 == in_use {
            return Some(found);
        }
        let train_score = detector.model().train_score;
        for at in [best.0, in_use] {
            let blurred = self.frame_blurred;
            quantise_frame(self.palette(at), blurred, rgb, (width, height), indices);
            let view = IndexView::new(width, height, indices).expect("sized by the caller");
            if let Some(d) = detector
                .detect(view, scale)
                .filter(|d| counts(at, d, train_score, self.relit_fraction))
            {
                self.current = at;
                return Some(d);
            }
        }
        // The light in use found `found` on these very indices before; if
        // it did not again, "not found" is the safe answer.
        None
    }
}

/// Whether a detection under light `at` counts: under the training light
/// at [`crate::MIN_FOUND_MARGIN`] of the model's threshold, under any
/// other at `relit_fraction` of the
/// training score ([`RELIT_SCORE_FRACTION`] unless measuring).
fn counts(at: (usize, usize), d: &Detection, train_score: f32, relit_fraction: f32) -> bool {
    at == TRAINING || d.score >= relit_fraction * train_score
}

/// Relit palettes kept per process, at most this many (about 256 KB
/// each: four palettes' whole grids).
const SHARED_CAPACITY: usize = 4 * EXPOSURES.len() * COLOUR_TEMPERATURES_K.len();

/// The palettes relit by any search of this process. Evaluations run one
/// chain per worker, and each built the same tables again (68 ms each,
/// most of an imaged confidence-training run's time).
type SharedRelit = Mutex<HashMap<(u64, (usize, usize)), Arc<Palette>>>;

fn shared_relit(base: &Palette, fingerprint: u64, at: (usize, usize)) -> Arc<Palette> {
    static SHARED: OnceLock<SharedRelit> = OnceLock::new();
    let shared = SHARED.get_or_init(Default::default);
    let key = (fingerprint, at);
    if let Some(p) = shared.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return p.clone();
    }
    // Built outside the lock: two workers may build one table at once, and
    // the second keeps the first's.
    let relit = Arc::new(
        base.relit(gains(at))
            .expect("the grid's gains are finite and positive"),
    );
    let mut map = shared.lock().unwrap_or_else(|e| e.into_inner());
    if map.len() >= SHARED_CAPACITY {
        map.clear();
    }
    map.entry(key).or_insert(relit).clone()
}

/// What identifies a palette's lookup tables: its colour space, centres
/// and reject distance.
fn fingerprint(palette: &Palette) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    format!("{:?}", palette.space()).hash(&mut h);
    palette.reject_distance().to_bits().hash(&mut h);
    for c in palette.centres() {
        c.map(f32::to_bits).hash(&mut h);
    }
    h.finish()
}

/// `rgb` quantised by `palette` into `out`, smoothed as the palette
/// smooths unless it is already `blurred`
/// ([`LightSearch::set_frame_blurred`]).
fn quantise_frame(
    palette: &Palette,
    blurred: bool,
    rgb: &[u8],
    (width, height): (u32, u32),
    out: &mut [u8],
) {
    let smoothing = if blurred {
        Smoothing::Off
    } else {
        palette.smoothing()
    };
    palette.quantise_into_slice_smoothed(rgb, width, height, out, smoothing);
}

/// The `k`-th nearest of `0..n` to `at`, `at` left out, the lower of two
/// at one distance first.
fn nth_nearest(n: usize, at: usize, k: usize) -> usize {
    let mut seen = 0;
    for d in 1..n {
        for i in [at.checked_sub(d), Some(at + d).filter(|&i| i < n)]
            .into_iter()
            .flatten()
        {
            if seen == k {
                return i;
            }
            seen += 1;
        }
    }
    unreachable!("k < n - 1 neighbours")
}

/// The linear gains of grid light `(exposure, colour temperature)`.
fn gains((e, t): (usize, usize)) -> [f32; 3] {
    colour_temperature_gains(COLOUR_TEMPERATURES_K[t]).map(|g| g * EXPOSURES[e])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_training_light_is_where_the_grids_say_and_has_unit_gains() {
        assert_eq!(EXPOSURES[TRAINING.0], 1.0);
        assert_eq!(COLOUR_TEMPERATURES_K[TRAINING.1], TRAINING_LIGHT_K);
        assert!(gains(TRAINING).iter().all(|g| (g - 1.0).abs() < 1e-5));
        const { assert!(RELIT_SCORE_FRACTION < WEAK_SCORE_FRACTION) };
    }

    #[test]
    fn the_neighbours_are_every_other_exposure_and_colour_nearest_first() {
        let palette = Palette::from_centres(
            acch_core::ColourSpace::Lab,
            vec![[50.0, 0.0, 0.0]],
            f32::INFINITY,
        )
        .unwrap();
        let search = LightSearch::new(&palette, CANDIDATES);
        let list: Vec<_> = (0..CANDIDATES).map(|k| search.candidate(k)).collect();
        assert_eq!(&list[..4], &[(7, 3), (9, 3), (6, 3), (10, 3)]);
        assert_eq!(list[13], (0, 3));
        assert_eq!(&list[14..17], &[(8, 2), (8, 4), (8, 1)]);
        assert!(list.iter().all(|&at| at != TRAINING));
        let mut unique = list.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), CANDIDATES);
    }
}
