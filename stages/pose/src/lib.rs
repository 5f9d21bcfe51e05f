//! 2-DOF pose from the ACCH of a segmented object: the match-value response
//! over every training view, its maximum (winner takes all), and a
//! refinement between grid points.
//!
//! Training lives here too ([`train`]): it turns labelled, masked views into a
//! [`ViewDatabase`]. Where the views come from (renderer, image folder) is the
//! caller's business.

#![warn(missing_docs)]

pub mod colour_map;
pub mod train;

pub use colour_map::{ViewMaps, store_view_maps, view_maps};

use acch_core::{HistogramExtractor, HistogramKind, IndexImage, Rect, ViewDatabase};
use std::sync::Arc;

/// Why an estimator could not be built.
#[derive(Debug, thiserror::Error)]
pub enum PoseError {
    /// The database has no views.
    #[error("the view database has no views")]
    Empty,
    /// The database's histogram parameters are invalid.
    #[error(transparent)]
    Params(#[from] acch_core::histogram::HistogramError),
}

/// Section of a [`ViewDatabase`] holding the roll search it was trained
/// for (degrees, `f32` little-endian): its confidence network's (the
/// network has seen the responses that search makes), or for a database
/// from photographs the rolls they show. A run uses it unless told
/// otherwise. Absent: 0, no search.
pub const ROLL_SEARCH_SECTION: &str = "roll-search";

/// The roll search `db` was trained with, degrees (0 when it says none).
/// A section of another length is an old or foreign file: 0 as well.
pub fn trained_roll_search_deg(db: &ViewDatabase) -> f32 {
    db.sections
        .get(ROLL_SEARCH_SECTION)
        .and_then(|b| <[u8; 4]>::try_from(b.as_slice()).ok())
        .map(f32::from_le_bytes)
        .filter(|d| d.is_finite() && *d > 0.0)
        .unwrap_or(0.0)
}

/// Records in `db` the roll search up to `max_deg` it was trained for
/// ([`ROLL_SEARCH_SECTION`]; 0 removes the record: a database trained
/// without the search stays byte-identical to one from before the record).
pub fn store_roll_search_deg(db: &mut ViewDatabase, max_deg: f32) {
    if max_deg > 0.0 {
        db.sections.insert(
            ROLL_SEARCH_SECTION.to_owned(),
            max_deg.to_le_bytes().to_vec(),
        );
    } else {
        db.sections.remove(ROLL_SEARCH_SECTION);
    }
}

/// Section of a [`ViewDatabase`] holding each view's pixel pairs at the
/// training scale (`f32` little-endian, one per view, in view order): what
/// [`Matching::Visible`] compares a query's pairs with. Absent (databases
/// trained before it), the match is [`Matching::Normalised`].
pub const VIEW_PAIRS_SECTION: &str = "view-pairs";

/// Each view's pixel pairs at the training scale, when `db` records them
/// for every view (a section of another length is refused: `None`).
pub fn view_pairs(db: &ViewDatabase) -> Option<Vec<f32>> {
    let bytes = db.sections.get(VIEW_PAIRS_SECTION)?;
    if bytes.len() != 4 * db.views().len() {
        return None;
    }
    let pairs: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    pairs
        .iter()
        .all(|p| p.is_finite() && *p > 0.0)
        .then_some(pairs)
}

/// Records each view's pixel pairs at the training scale in `db`.
pub fn store_view_pairs(db: &mut ViewDatabase, pairs: &[f32]) {
    let bytes = pairs.iter().flat_map(|p| p.to_le_bytes()).collect();
    db.sections.insert(VIEW_PAIRS_SECTION.to_owned(), bytes);
}

/// Section of a [`ViewDatabase`] holding each view's colour layout (see
/// [`acch_core::layout`]; `f32` little-endian, `3 x C` per view in view
/// order, offsets in pixels at the training scale). Absent (databases
/// trained before it), the response is the histograms' alone.
pub const VIEW_LAYOUTS_SECTION: &str = "view-layouts";

/// Each view's colour layout, when `db` records one for every view (a
/// section of another length or with a value that is not finite is
/// refused: `None`).
pub fn view_layouts(db: &ViewDatabase) -> Option<Vec<f32>> {
    let bytes = db.sections.get(VIEW_LAYOUTS_SECTION)?;
    let len = db.views().len() * db.params.colours as usize * acch_core::LAYOUT_FIELDS;
    if bytes.len() != 4 * len {
        return None;
    }
    let layouts: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    layouts.iter().all(|v| v.is_finite()).then_some(layouts)
}

/// Records each view's colour layout in `db` (views in order, `3 x C`
/// each).
pub fn store_view_layouts(db: &mut ViewDatabase, layouts: &[f32]) {
    let bytes = layouts.iter().flat_map(|v| v.to_le_bytes()).collect();
    db.sections.insert(VIEW_LAYOUTS_SECTION.to_owned(), bytes);
}

/// Match value a view gives up per object size (the square root of its
/// area) that its colour layout lies from the query's. Chosen on the
/// robust protocol's development seed (docs/accuracy.md).
pub const LAYOUT_WEIGHT: f32 = 0.5;

/// How a query's histogram is matched with a view's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Matching {
    /// The paper's match value (eq. 2): the intersection of the normalised
    /// histograms. A part of the object (the rest hidden) is compared with
    /// the whole view's distribution, diluted by the pairs it lacks, and a
    /// view whose whole resembles that part wins.
    Normalised,
    /// The share of the query's pairs that the whole view holds, each
    /// view's histogram taken at its own pair count at the query's scale
    /// ([`acch_core::scaled_intersection`]): a visible part of the right
    /// view matches it fully; a smaller view than the query cannot hold
    /// all its pairs. Needs the views' pair counts ([`view_pairs`]).
    Visible,
}

/// Matches the normalised histogram `query` with every view of `db` into
/// `out`: by the visible part when `visible` holds the views' pairs at the
/// training scale and their factor to the query's pairs (the share of the
/// query's pairs each whole view holds), else by the paper's normalised
/// match value. The views are shared with `helper`'s thread when given
/// ([`acch_core::share::in_turn`]; the same values either way).
fn match_views(
    db: &ViewDatabase,
    visible: Option<(&[f32], f32)>,
    query: &[f32],
    out: &mut [f32],
    helper: Option<&rayon::ThreadPool>,
) {
    match (visible, helper) {
        (Some((view_pairs, k)), None) => {
            for (i, (r, n)) in out.iter_mut().zip(view_pairs).enumerate() {
                *r = acch_core::scaled_intersection(query, db.histogram(i), n * k);
            }
        }
        (Some((view_pairs, k)), Some(pool)) => {
            let matched =
                acch_core::share::in_turn(Some(pool), out.len(), &mut (), &mut (), |i, _| {
                    acch_core::scaled_intersection(query, db.histogram(i), view_pairs[i] * k)
                });
            out.copy_from_slice(&matched);
        }
        (None, _) => db.response_into(query, out),
    }
}

/// Each view's pairs at the training scale (`view_pairs`, recorded by the
/// database) when `matching` matches the views by their visible part.
fn visible_pairs(view_pairs: Option<&[f32]>, matching: Matching) -> Option<&[f32]> {
    match (view_pairs, matching) {
        (Some(pairs), Matching::Visible) => Some(pairs),
        _ => None,
    }
}

/// Lowers each view's match value in `out` by [`LAYOUT_WEIGHT`] times how
/// far its colour layout (of `layouts`, view after view) lies from
/// `layout` (at the training scale, upright), over the view's size.
fn penalise_layouts(db: &ViewDatabase, layouts: &[f32], layout: &[f32], out: &mut [f32]) {
    for ((r, l), v) in out
        .iter_mut()
        .zip(layouts.chunks_exact(layout.len()))
        .zip(db.views())
    {
        let d = acch_core::layout_distance(layout, l) / v.size_px.max(1.0);
        *r = (*r - LAYOUT_WEIGHT * d).max(0.0);
    }
}

/// Whether [`PoseEstimator::respond_at`] measures the query's colour
/// layout or reuses the last one measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Layout {
    Measure,
    Reuse,
}

/// One θ slice of the response: consecutive views with the same elevation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Slice {
    /// Elevation of the slice, degrees.
    pub theta_deg: f32,
    /// Index of its first view.
    pub start: usize,
    /// Number of views.
    pub len: usize,
}

/// How the estimate is read off the response.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Refinement {
    /// The best view's (θ, φ): the paper's winner takes all.
    WinnerTakesAll,
    /// A parabola through the peak and its neighbours, in φ within the slice
    /// and in θ across slices.
    #[default]
    Parabolic,
}

/// A 2-DOF estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Elevation, degrees.
    pub theta_deg: f32,
    /// Azimuth, degrees in [0, 360).
    pub phi_deg: f32,
    /// Index of the best view.
    pub best_view: usize,
    /// Its match value.
    pub best_value: f32,
    /// Scale the histogram was computed at.
    pub scale: f32,
    /// The camera's roll about its optical axis, degrees (the image turned
    /// counter-clockwise by it against the training views); 0 when the
    /// roll is not searched.
    pub roll_deg: f32,
}

/// Views whose rolled matches are searched: the best by the roll-invariant
/// part of the histogram. Measured (docs/accuracy.md): the true view is
/// among them on the protocols' rolled views.
pub const ROLL_SHORTLIST: usize = 16;

/// The roll search: the query's ACCH turned by whole orientation bins, at
/// the views that match it best whatever the roll.
struct RollSearch {
    /// Largest turn searched, in orientation bins either way.
    max_shift: i32,
    /// Degrees per orientation bin.
    bin_deg: f32,
    /// Every view's roll-invariant part (colours x colours each), as the
    /// fraction of its pairs.
    invariant: Vec<f32>,
    /// The query's roll-invariant part.
    query_invariant: Vec<f32>,
    /// The query turned by one shift.
    rolled: Vec<f32>,
    /// The shortlisted views.
    shortlist: [(usize, f32); ROLL_SHORTLIST],
}

/// Splits views into θ slices (runs of equal elevation, in database order).
pub fn slices(db: &ViewDatabase) -> Vec<Slice> {
    let mut out: Vec<Slice> = Vec::new();
    for (i, v) in db.views().iter().enumerate() {
        match out.last_mut() {
            Some(s) if s.theta_deg == v.theta_deg => s.len += 1,
            _ => out.push(Slice {
                theta_deg: v.theta_deg,
                start: i,
                len: 1,
            }),
        }
    }
    out
}

/// Smallest angle between two azimuths, degrees in [0, 180].
pub fn phi_error(a: f32, b: f32) -> f32 {
    let d = (a - b).rem_euclid(360.0);
    d.min(360.0 - d)
}

/// Estimates poses against one database, reusing its buffers (no allocation
/// per frame once warm, unless it shares the matching with a helper).
pub struct PoseEstimator {
    db: ViewDatabase,
    slices: Vec<Slice>,
    /// Slice of each view.
    slice_of: Vec<usize>,
    extractor: HistogramExtractor,
    histogram: Vec<f32>,
    response: Vec<f32>,
    median_size: f32,
    roll: Option<RollSearch>,
    /// The roll found by the last [`Self::respond`], degrees.
    last_roll_deg: f32,
    /// Each view's pairs at the training scale, for [`Matching::Visible`].
    view_pairs: Option<Vec<f32>>,
    /// The extractor's pair rate at the training scale.
    rate_at_training: f32,
    matching: Matching,
    /// Each view's colour layout, when the database records them.
    view_layouts: Option<Vec<f32>>,
    /// The last query's colour layout as measured (pixels of the image).
    measured_layout: Vec<f32>,
    /// The same at the training scale and upright: what the views are
    /// compared with.
    layout: Vec<f32>,
    /// Each view's colour map, when the database records them.
    view_maps: Option<ViewMaps>,
    /// The last query's map, for [`Self::map_rival`].
    placed: acch_core::PlacedQuery,
    /// A thread that shares the matching ([`Self::share_matching_with`]).
    helper: Option<Arc<rayon::ThreadPool>>,
}

impl PoseEstimator {
    /// An estimator over `db`.
    pub fn new(mut db: ViewDatabase) -> Result<Self, PoseError> {
        if db.views().is_empty() {
            return Err(PoseError::Empty);
        }
        // Read once into their own fields below: the sections' bytes would
        // be a second copy (the maps are 4-6 MB an object, in every stage
        // that holds an estimator).
        let (view_layouts, view_maps) = (view_layouts(&db), view_maps(&db));
        for parsed in [VIEW_LAYOUTS_SECTION, colour_map::VIEW_MAPS_SECTION] {
            db.sections.remove(parsed);
        }
        let mut extractor = HistogramExtractor::new(db.params)?;
        let rate_at_training = extractor.pair_rate(1.0);
        let slices = slices(&db);
        let mut slice_of = vec![0; db.views().len()];
        for (k, s) in slices.iter().enumerate() {
            slice_of[s.start..s.start + s.len].fill(k);
        }
        Ok(PoseEstimator {
            histogram: vec![0.0; db.params.len()],
            response: vec![0.0; db.views().len()],
            median_size: db.median_size_px(),
            slices,
            slice_of,
            extractor,
            roll: None,
            last_roll_deg: 0.0,
            matching: if view_pairs(&db).is_some() {
                Matching::Visible
            } else {
                Matching::Normalised
            },
            view_pairs: view_pairs(&db),
            rate_at_training,
            view_layouts,
            measured_layout: vec![0.0; db.params.colours as usize * acch_core::LAYOUT_FIELDS],
            layout: vec![0.0; db.params.colours as usize * acch_core::LAYOUT_FIELDS],
            view_maps,
            placed: acch_core::PlacedQuery::default(),
            helper: None,
            db,
        })
    }

    /// Matches by `matching` instead of the default (visible-part matching
    /// where the database records the views' pair counts); a database
    /// without them matches normalised whatever is asked.
    pub fn with_matching(mut self, matching: Matching) -> Self {
        self.matching = match self.view_pairs {
            Some(_) => matching,
            None => Matching::Normalised,
        };
        self
    }

    /// How the views are matched.
    pub fn matching(&self) -> Matching {
        self.matching
    }

    /// Searches the camera's roll up to `max_deg` either way (rounded to
    /// whole orientation bins of the ACCH, refined between them); 0 turns
    /// the search off. Only an ACCH has orientations to turn.
    pub fn with_roll_search(mut self, max_deg: f32) -> Self {
        let p = self.db.params;
        if max_deg.is_nan() || max_deg <= 0.0 || p.kind != HistogramKind::Acch {
            self.roll = None;
            return self;
        }
        let (c, d) = (p.colours as usize, p.geometric_bins());
        let bin_deg = 180.0 / d as f32;
        let n = self.db.views().len();
        let mut invariant = vec![0.0; n * c * c];
        for (i, out) in invariant.chunks_exact_mut(c * c).enumerate() {
            acch_core::roll_invariant(self.db.histogram(i), c, out);
        }
        let max_shift = ((max_deg / bin_deg).round() as i32).clamp(1, d as i32);
        self.roll = Some(RollSearch {
            max_shift,
            bin_deg,
            invariant,
            query_invariant: vec![0.0; c * c],
            rolled: vec![0.0; p.len()],
            shortlist: [(0, 0.0); ROLL_SHORTLIST],
        });
        self
    }

    /// The largest roll searched, degrees (0: none).
    pub fn roll_search_deg(&self) -> f32 {
        self.roll
            .as_ref()
            .map_or(0.0, |r| r.max_shift as f32 * r.bin_deg)
    }

    /// The database.
    pub fn database(&self) -> &ViewDatabase {
        &self.db
    }

    /// The θ slices of the database.
    pub fn slices(&self) -> &[Slice] {
        &self.slices
    }

    /// The response of the last estimate: match value per view.
    pub fn response(&self) -> &[f32] {
        &self.response
    }

    /// The histogram of the last estimate.
    pub fn histogram(&self) -> &[f32] {
        &self.histogram
    }

    /// Scale at which an object at `distance_m` metres looks, relative to
    /// training.
    pub fn scale_for_distance(&self, distance_m: f32) -> f32 {
        self.db.train_distance_m / distance_m
    }

    /// Shares the matching of a query with every view with `pool`'s first
    /// thread ([`acch_core::share::in_turn`]): the same response, sooner.
    pub fn share_matching_with(&mut self, pool: Arc<rayon::ThreadPool>) {
        self.helper = Some(pool);
    }

    /// Computes the histogram of the masked ROI at `scale` and the response
    /// against every view; returns the number of pixel pairs counted.
    pub fn respond(
        &mut self,
        image: &IndexImage,
        mask: Option<&[u8]>,
        roi: Rect,
        scale: f32,
    ) -> u64 {
        self.respond_at(image, mask, roi, scale, Layout::Measure)
    }

    /// [`Self::respond`]; `layout` says whether the query's colour layout
    /// is measured or the last one is reused (the same image, mask and ROI
    /// at another scale: the layout does not depend on the scale until it
    /// is scaled).
    fn respond_at(
        &mut self,
        image: &IndexImage,
        mask: Option<&[u8]>,
        roi: Rect,
        scale: f32,
        layout: Layout,
    ) -> u64 {
        let pairs = self
            .extractor
            .extract(image, mask, roi, scale, &mut self.histogram);
        self.last_roll_deg = 0.0;
        if pairs > 0
            && let Some(search) = &mut self.roll
        {
            // Turned back by the roll found, the histogram is a training
            // view's again: the response is over it.
            let (shift, roll_deg) = search.find(&self.db, &self.histogram);
            self.last_roll_deg = roll_deg;
            if shift != 0 {
                let p = self.db.params;
                acch_core::roll_acch(
                    &self.histogram,
                    p.colours as usize,
                    p.geometric_bins(),
                    shift,
                    &mut search.rolled,
                );
                self.histogram.copy_from_slice(&search.rolled);
            }
        }
        let visible = match visible_pairs(self.view_pairs.as_deref(), self.matching) {
            // A whole view's pairs at this scale, over the query's.
            Some(p) if pairs > 0 => Some((
                p,
                self.extractor.pair_rate(scale) / self.rate_at_training / pairs as f32,
            )),
            _ => None,
        };
        match_views(
            &self.db,
            visible,
            &self.histogram,
            &mut self.response,
            self.helper.as_deref(),
        );
        if pairs > 0
            && scale > 0.0
            && let Some(layouts) = &self.view_layouts
        {
            // Views whose colours sit elsewhere match less: what tells
            // apart the turns of an object the histogram sees alike.
            if layout == Layout::Measure {
                acch_core::layout_into(image, mask, roi, &mut self.measured_layout);
            }
            self.layout.copy_from_slice(&self.measured_layout);
            acch_core::scale_layout(&mut self.layout, 1.0 / scale);
            acch_core::unroll_layout(&mut self.layout, self.last_roll_deg);
            penalise_layouts(&self.db, layouts, &self.layout, &mut self.response);
        }
        pairs
    }

    /// The response a clean query that is training view `a` itself would
    /// get (its histogram and layout as trained, at the training scale,
    /// upright) into `out`: how alike the database's own views are, so how
    /// far any estimate from it could tell view `a` from each other view.
    ///
    /// # Panics
    /// When `a` is not a view or `out` is not one value per view.
    pub fn respond_to_view(&self, a: usize, out: &mut [f32]) {
        assert_eq!(out.len(), self.db.views().len(), "response length");
        let visible =
            visible_pairs(self.view_pairs.as_deref(), self.matching).map(|p| (p, 1.0 / p[a]));
        match_views(&self.db, visible, self.db.histogram(a), out, None);
        if let Some(layouts) = &self.view_layouts {
            let per_view = self.layout.len();
            let own = &layouts[a * per_view..(a + 1) * per_view];
            penalise_layouts(&self.db, layouts, own, out);
        }
    }

    /// Estimates the pose of the masked object in `roi`. `scale` is the
    /// object's apparent size relative to training when known (from the
    /// distance); `None` derives it from the mask's area against the
    /// training views, checked once against the best view's own size.
    /// Returns `None` when the region holds no object colour pairs.
    pub fn estimate(
        &mut self,
        image: &IndexImage,
        mask: Option<&[u8]>,
        roi: Rect,
        scale: Option<f32>,
        refinement: Refinement,
    ) -> Option<Estimate> {
        let (scale, best) = match scale {
            Some(s) => {
                if self.respond(image, mask, roi, s) == 0 {
                    return None;
                }
                (s, self.best())
            }
            None => {
                let size = object_size(image, mask, roi);
                if size == 0.0 {
                    return None;
                }
                let s0 = size / self.median_size;
                if self.respond(image, mask, roi, s0) == 0 {
                    return None;
                }
                let best = self.best();
                // Apparent size changes with the view; once a view is chosen,
                // its own training size gives a better scale.
                let s1 = size / self.db.views()[best].size_px;
                if (s1 / s0 - 1.0).abs() > 0.05 {
                    self.respond_at(image, mask, roi, s1, Layout::Reuse);
                    (s1, self.best())
                } else {
                    (s0, best)
                }
            }
        };
        let (theta_deg, phi_deg) = match refinement {
            Refinement::WinnerTakesAll => {
                let v = self.db.views()[best];
                (v.theta_deg, v.phi_deg)
            }
            Refinement::Parabolic => self.refine(best),
        };
        Some(Estimate {
            theta_deg,
            phi_deg: phi_deg.rem_euclid(360.0),
            best_view: best,
            best_value: self.response[best],
            scale,
            roll_deg: self.last_roll_deg,
        })
    }

    /// How much of the masked object in `roi` a training view explains:
    /// the share of its pixels the palette mapped to an object colour,
    /// times the best view's match value. It compares one region's
    /// indices under several lights: the match value alone favours a
    /// light that maps few pixels (what is left matches some view well),
    /// the share alone one that maps many to the wrong colours. `None`
    /// when the region holds no object colour pairs.
    pub fn explained(
        &mut self,
        image: &IndexImage,
        mask: &[u8],
        roi: Rect,
        scale: Option<f32>,
    ) -> Option<f32> {
        let roi = roi.clamp_to(image.width, image.height);
        let w = image.width as usize;
        let (mut object, mut mapped) = (0u32, 0u32);
        for y in roi.y as usize..(roi.y + roi.height) as usize {
            let span = y * w + roi.x as usize..y * w + (roi.x + roi.width) as usize;
            for (&m, &i) in mask[span.clone()].iter().zip(&image.data[span]) {
                object += u32::from(m != 0);
                mapped += u32::from(m != 0 && i != acch_core::NOT_OBJECT);
            }
        }
        let e = self.estimate(image, Some(mask), roi, scale, Refinement::WinnerTakesAll)?;
        Some(mapped as f32 / object.max(1) as f32 * e.best_value)
    }

    /// Index of the best view of the last response.
    pub fn best(&self) -> usize {
        argmax(&self.response)
    }

    /// The `k` best views of the last response, best first.
    pub fn top(&self, k: usize) -> Vec<(usize, f32)> {
        let mut idx: Vec<usize> = (0..self.response.len()).collect();
        idx.sort_by(|&a, &b| self.response[b].total_cmp(&self.response[a]));
        idx.truncate(k);
        idx.into_iter().map(|i| (i, self.response[i])).collect()
    }

    /// Parabolic refinement around view `best`.
    fn refine(&self, best: usize) -> (f32, f32) {
        let views = self.db.views();
        // The paper's match value around the best view: visible-part
        // matching saturates at 1 for every view that holds the query
        // (neighbours a little larger), so it has no peak to fit (robust
        // protocol, 10 generated objects, seed 3, clean: E(θ) 2.67° refined
        // on visible-part values, 1.06° on these).
        let r = |i: usize| match self.matching {
            Matching::Normalised => self.response[i],
            Matching::Visible => acch_core::match_value(&self.histogram, self.db.histogram(i)),
        };
        let s = self.slices[self.slice_of[best]];
        let k = best - s.start;
        // φ: neighbours in the same slice, wrapping around 360°.
        let mut phi = views[best].phi_deg;
        if s.len >= 3 {
            let prev = s.start + (k + s.len - 1) % s.len;
            let next = s.start + (k + 1) % s.len;
            let step = phi_error(views[next].phi_deg, views[prev].phi_deg) / 2.0;
            let (a, b, c) = (r(prev), r(best), r(next));
            let denom = a - 2.0 * b + c;
            if denom < 0.0 && step > 0.0 {
                let delta = (0.5 * (a - c) / denom).clamp(-0.5, 0.5);
                phi += delta * step;
            }
        }
        // θ: the same azimuth in the neighbouring slices, whose spacing may
        // differ (45, 50, 60, ...): fit a parabola through three points, or
        // move toward the better neighbour at the edge of the grid.
        let theta0 = views[best].theta_deg;
        let slice_k = self.slice_of[best];
        let at = |slice: usize| -> Option<(f32, f32)> {
            let sl = self.slices.get(slice)?;
            let j = (sl.start..sl.start + sl.len).min_by(|&x, &y| {
                phi_error(views[x].phi_deg, views[best].phi_deg)
                    .total_cmp(&phi_error(views[y].phi_deg, views[best].phi_deg))
            })?;
            Some((sl.theta_deg, r(j)))
        };
        let lower = slice_k.checked_sub(1).and_then(at);
        let upper = at(slice_k + 1);
        let b = r(best);
        let theta = match (lower, upper) {
            (Some(p0), Some(p2)) => parabola_vertex(p0, (theta0, b), p2)
                .map(|v| v.clamp((p0.0 + theta0) / 2.0, (theta0 + p2.0) / 2.0)),
            // At the edge of the grid (θ = 90 or the lowest slice), fit the
            // edge and its two inner neighbours: the peak may lie up to half
            // a step inside, never beyond the edge.
            (Some(p1), None) => slice_k
                .checked_sub(2)
                .and_then(at)
                .and_then(|p0| parabola_vertex(p0, p1, (theta0, b)))
                .map(|v| v.clamp((p1.0 + theta0) / 2.0, theta0)),
            (None, Some(p1)) => at(slice_k + 2)
                .and_then(|p2| parabola_vertex((theta0, b), p1, p2))
                .map(|v| v.clamp(theta0, (theta0 + p1.0) / 2.0)),
            (None, None) => None,
        }
        .unwrap_or(theta0);
        (theta, phi)
    }
}

/// x of the vertex of the parabola through three points (distinct x);
/// `None` if the parabola opens upward (no maximum).
/// Match value given up per bin of roll searched away from upright: near
/// θ = 90° a turn in φ and a roll are nearly the same rotation, and
/// between two such readings the one with less roll is the likelier for
/// a camera that mostly stays upright. Chosen on table1, development seed
/// 1 (docs/accuracy.md): 0.005 keeps 99 % of rolled views' rotations
/// within 10° and halves the φ failures of unrolled views against none.
const ROLL_PRIOR: f32 = 0.005;

impl RollSearch {
    /// The turn of `query` (whole bins) that best matches a shortlisted
    /// view, and the camera's roll it stands for, refined between bins.
    fn find(&mut self, db: &ViewDatabase, query: &[f32]) -> (i32, f32) {
        let p = db.params;
        let (c, d) = (p.colours as usize, p.geometric_bins());
        acch_core::roll_invariant(query, c, &mut self.query_invariant);
        // The shortlist: the best views whatever the roll (kept sorted,
        // best first, in a fixed array: no allocation per frame).
        self.shortlist = [(usize::MAX, f32::NEG_INFINITY); ROLL_SHORTLIST];
        for (i, h) in self.invariant.chunks_exact(c * c).enumerate() {
            let v = acch_core::intersection(&self.query_invariant, h);
            if v > self.shortlist[ROLL_SHORTLIST - 1].1 {
                let mut k = ROLL_SHORTLIST - 1;
                while k > 0 && self.shortlist[k - 1].1 < v {
                    self.shortlist[k] = self.shortlist[k - 1];
                    k -= 1;
                }
                self.shortlist[k] = (i, v);
            }
        }
        let (mut best, mut best_shift, mut best_view) = (f32::NEG_INFINITY, 0i32, usize::MAX);
        for shift in -self.max_shift..=self.max_shift {
            acch_core::roll_acch(query, c, d, shift, &mut self.rolled);
            for &(view, _) in self.shortlist.iter().filter(|(v, _)| *v != usize::MAX) {
                let v = acch_core::intersection(&self.rolled, db.histogram(view))
                    - ROLL_PRIOR * shift.unsigned_abs() as f32;
                if v > best {
                    (best, best_shift, best_view) = (v, shift, view);
                }
            }
        }
        // Between bins: a parabola through the best view's values at the
        // neighbouring turns.
        let mut delta = 0.0;
        if best_view != usize::MAX && best_shift.abs() < self.max_shift {
            let mut at = |shift: i32| {
                acch_core::roll_acch(query, c, d, shift, &mut self.rolled);
                acch_core::intersection(&self.rolled, db.histogram(best_view))
            };
            let (a, b, cc) = (at(best_shift - 1), at(best_shift), at(best_shift + 1));
            let denom = a - 2.0 * b + cc;
            if denom < 0.0 {
                delta = (0.5 * (a - cc) / denom).clamp(-0.5, 0.5);
            }
        }
        // Turning the image back by `shift` bins undoes a camera roll of
        // -shift bins (the image turns counter-clockwise as the camera
        // rolls).
        (best_shift, -(best_shift as f32 + delta) * self.bin_deg)
    }
}

fn parabola_vertex(p0: (f32, f32), p1: (f32, f32), p2: (f32, f32)) -> Option<f32> {
    let (x0, y0) = p0;
    let (x1, y1) = p1;
    let (x2, y2) = p2;
    let d01 = (y1 - y0) / (x1 - x0);
    let d12 = (y2 - y1) / (x2 - x1);
    let a = (d12 - d01) / (x2 - x0);
    // Only a downward parabola has a maximum (NaN from equal x is refused too).
    if a.is_nan() || a >= 0.0 {
        return None;
    }
    let b = d01 - a * (x0 + x1);
    Some(-b / (2.0 * a))
}

fn argmax(v: &[f32]) -> usize {
    let mut best = 0;
    for (i, &x) in v.iter().enumerate() {
        if x > v[best] {
            best = i;
        }
    }
    best
}

/// Apparent size of the object in `roi`: the square root of its mask area
/// (pixels whose mask byte is non-zero), or of the ROI without a mask.
pub fn object_size(image: &IndexImage, mask: Option<&[u8]>, roi: Rect) -> f32 {
    let roi = roi.clamp_to(image.width, image.height);
    let area = match mask {
        None => roi.area(),
        Some(m) => {
            let w = image.width as usize;
            (roi.y as usize..(roi.y + roi.height) as usize)
                .map(|y| {
                    let row = &m[y * w + roi.x as usize..y * w + (roi.x + roi.width) as usize];
                    row.iter().filter(|&&b| b != 0).count() as u64
                })
                .sum()
        }
    };
    (area as f32).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64 x 64 view: vertical red and green stripes where `stripes`
    /// says, blue elsewhere, yellow in the top `band` rows.
    fn painted(stripes: impl Fn(usize) -> bool, band: usize) -> Vec<u8> {
        (0..64 * 64)
            .flat_map(|i| {
                let (x, y) = (i % 64, i / 64);
                if y < band {
                    [220, 220, 30]
                } else if !stripes(x) {
                    [30, 30, 200]
                } else if (x / 4) % 2 == 0 {
                    [200, 30, 30]
                } else {
                    [30, 200, 30]
                }
            })
            .collect()
    }

    #[test]
    fn a_visible_part_of_a_view_matches_it_whole_where_the_normalised_match_takes_another() {
        let left = |x: usize| x < 32;
        // View A: stripes on the left half, blue on the right. View B: the
        // left half alone, stripes under a yellow band.
        let a = painted(left, 0);
        let b = painted(|_| true, 16);
        let full = vec![255u8; 64 * 64];
        let half: Vec<u8> = (0..64 * 64)
            .map(|i| if left(i % 64) { 255 } else { 0 })
            .collect();
        let config = train::TrainConfig {
            colours: 8,
            ..train::TrainConfig::default()
        };
        let views = [
            train::LabelledView::new(&a, &full, (64, 64), (60.0, 0.0), 1.0),
            train::LabelledView::new(&b, &half, (64, 64), (60.0, 90.0), 1.0),
        ];
        let db = train::build_database("o", 1.0, &views, &config).unwrap();
        assert!(
            view_pairs(&db).is_some(),
            "training records the views' pairs"
        );
        // View A with its right half hidden.
        let index = db.palette.quantise(&a, 64, 64);
        let roi = train::mask_bbox(&half, 64, 64).unwrap();
        let best = |matching| {
            let mut e = PoseEstimator::new(db.clone())
                .unwrap()
                .with_matching(matching);
            let est = e
                .estimate(
                    &index,
                    Some(&half),
                    roi,
                    Some(1.0),
                    Refinement::WinnerTakesAll,
                )
                .unwrap();
            (est.phi_deg, est.best_value)
        };
        let (phi, value) = best(Matching::Visible);
        assert_eq!(phi, 0.0, "visible-part matching takes view A");
        assert!(
            value > 0.95,
            "A holds every pair of its visible part: {value}"
        );
        assert_eq!(
            best(Matching::Normalised).0,
            90.0,
            "the normalised match takes B"
        );
    }

    /// An 80 x 80 view of a lid from above: a teal disc (radius 30) with a
    /// yellow mark (radius 4) 8 px from its centre toward `mark_deg`, on
    /// grey; and its mask. Every pixel 10-20 px from the mark's centre is
    /// lid: the histogram can hardly see where the mark sits.
    fn lid(mark_deg: f32) -> (Vec<u8>, Vec<u8>) {
        let (s, c) = mark_deg.to_radians().sin_cos();
        let (mut rgb, mut mask) = (Vec::new(), Vec::new());
        for i in 0..80 * 80 {
            let (x, y) = ((i % 80) as f32 - 39.5, (i / 80) as f32 - 39.5);
            let (mx, my) = (x - 8.0 * c, y - 8.0 * s);
            let (inside, on_mark) = (x * x + y * y <= 900.0, mx * mx + my * my <= 16.0);
            rgb.extend(match (inside, on_mark) {
                (false, _) => [128, 128, 128],
                (true, false) => [0, 128, 128],
                (true, true) => [230, 200, 40],
            });
            mask.push(if inside { 255 } else { 0 });
        }
        (rgb, mask)
    }

    /// Twelve turns of [`lid`] (every 30°) from above, and `more` views,
    /// trained with four colours.
    fn lids_database(more: &[train::LabelledView]) -> ViewDatabase {
        let lids: Vec<_> = (0..12).map(|k| lid(k as f32 * 30.0)).collect();
        let mut views: Vec<_> = lids
            .iter()
            .enumerate()
            .map(|(k, (rgb, mask))| {
                train::LabelledView::new(rgb, mask, (80, 80), (90.0, k as f32 * 30.0), 1.0)
            })
            .collect();
        views.extend_from_slice(more);
        let config = train::TrainConfig {
            colours: 4,
            ..train::TrainConfig::default()
        };
        train::build_database("lid", 1.0, &views, &config).unwrap()
    }

    #[test]
    fn the_estimator_reads_the_views_layouts_and_maps_once_and_keeps_no_second_copy() {
        let db = lids_database(&[]);
        let parsed = [VIEW_LAYOUTS_SECTION, colour_map::VIEW_MAPS_SECTION];
        assert!(parsed.iter().all(|s| db.sections.contains_key(*s)));
        let e = PoseEstimator::new(db).unwrap();
        assert!(e.has_view_maps() && e.view_layouts.is_some());
        for s in parsed {
            assert!(!e.database().sections.contains_key(s), "{s} kept twice");
        }
    }

    #[test]
    fn a_lid_seen_from_above_is_told_apart_turned_by_its_layout() {
        let db = lids_database(&[]);
        assert!(view_layouts(&db).is_some(), "training records the layouts");
        let mut histogram_alone = db.clone();
        histogram_alone.sections.remove(VIEW_LAYOUTS_SECTION);
        // A section of another length (another palette's, a cut file) is
        // refused, not read across views.
        let mut cut = db.clone();
        cut.sections
            .get_mut(VIEW_LAYOUTS_SECTION)
            .unwrap()
            .truncate(8);
        assert!(view_layouts(&cut).is_none());
        let (rgb, mask) = lid(120.0);
        let index = db.palette.quantise(&rgb, 80, 80);
        let roi = train::mask_bbox(&mask, 80, 80).unwrap();
        let top2 = |db: &ViewDatabase| {
            let mut e = PoseEstimator::new(db.clone()).unwrap();
            let est = e
                .estimate(
                    &index,
                    Some(&mask),
                    roi,
                    Some(1.0),
                    Refinement::WinnerTakesAll,
                )
                .unwrap();
            let top = e.top(2);
            (est.phi_deg, top[0].1 - top[1].1)
        };
        let (_, margin) = top2(&histogram_alone);
        assert!(
            margin < 0.01,
            "the histogram alone sees every turn alike: {margin}"
        );
        let (phi, margin) = top2(&db);
        assert_eq!(phi, 120.0);
        assert!(margin > 0.01, "the layout sets the turn apart: {margin}");
    }

    #[test]
    fn a_view_as_its_own_query_is_rated_as_its_training_image_would_be() {
        let db = lids_database(&[]);
        let mut own = vec![0.0; db.views().len()];
        PoseEstimator::new(db.clone())
            .unwrap()
            .respond_to_view(4, &mut own);
        let (rgb, mask) = lid(120.0);
        let index = db.palette.quantise(&rgb, 80, 80);
        let roi = train::mask_bbox(&mask, 80, 80).unwrap();
        let mut seen = PoseEstimator::new(db.clone()).unwrap();
        seen.respond(&index, Some(&mask), roi, 1.0);
        for (i, (a, b)) in own.iter().zip(seen.response()).enumerate() {
            assert!((a - b).abs() < 1e-4, "view {i}: {a} as trained, {b} seen");
        }
        assert!(
            (own[4] - 1.0).abs() < 1e-4,
            "a view holds itself: {}",
            own[4]
        );
        let runner_up = |r: &[f32]| {
            r.iter()
                .enumerate()
                .filter(|&(i, _)| i != 4)
                .map(|(_, &v)| v)
                .fold(0f32, f32::max)
        };
        assert!(
            runner_up(&own) < own[4] - 0.01,
            "the layout tells the turns apart"
        );
        let mut histogram_alone = db;
        histogram_alone.sections.remove(VIEW_LAYOUTS_SECTION);
        PoseEstimator::new(histogram_alone)
            .unwrap()
            .respond_to_view(4, &mut own);
        assert!(
            runner_up(&own) > own[4] - 0.01,
            "the histograms alone do not"
        );
    }

    #[test]
    fn a_helper_thread_changes_no_bit_of_the_response() {
        let db = lids_database(&[]);
        let (rgb, mask) = lid(120.0);
        let index = db.palette.quantise(&rgb, 80, 80);
        let roi = train::mask_bbox(&mask, 80, 80).unwrap();
        let mut alone = PoseEstimator::new(db.clone()).unwrap();
        let mut shared = PoseEstimator::new(db).unwrap();
        assert!(shared.view_pairs.is_some(), "the visible part is matched");
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        shared.share_matching_with(Arc::new(pool));
        alone.respond(&index, Some(&mask), roi, 1.0);
        shared.respond(&index, Some(&mask), roi, 1.0);
        assert!(alone.response().iter().any(|&v| v > 0.5));
        assert_eq!(alone.response(), shared.response());
    }

    #[test]
    fn a_refined_scale_matches_the_layout_as_a_fresh_measurement_would() {
        // Lids at θ = 90 and, at θ = 80, more views of a smaller yellow
        // disc: the median view is small, so a lid's first scale is off
        // and refined against the lid view chosen.
        let disc: Vec<u8> = (0..80 * 80)
            .flat_map(|i| {
                let (x, y) = ((i % 80) as f32 - 39.5, (i / 80) as f32 - 39.5);
                if x * x + y * y <= 400.0 {
                    [230, 200, 40]
                } else {
                    [128, 128, 128]
                }
            })
            .collect();
        let disc_mask: Vec<u8> = disc
            .chunks_exact(3)
            .map(|p| if p[0] == 230 { 255 } else { 0 })
            .collect();
        let discs: Vec<_> = (0..13)
            .map(|k| {
                let phi = k as f32 * 27.0;
                train::LabelledView::new(&disc, &disc_mask, (80, 80), (80.0, phi), 1.0)
            })
            .collect();
        let db = lids_database(&discs);
        let (rgb, mask) = lid(120.0);
        let index = db.palette.quantise(&rgb, 80, 80);
        let roi = train::mask_bbox(&mask, 80, 80).unwrap();
        let mut refined = PoseEstimator::new(db.clone()).unwrap();
        let est = refined
            .estimate(&index, Some(&mask), roi, None, Refinement::WinnerTakesAll)
            .unwrap();
        let first = object_size(&index, Some(&mask), roi) / db.median_size_px();
        assert!(
            (est.scale / first - 1.0).abs() > 0.05,
            "the scale is refined: {first} -> {}",
            est.scale
        );
        assert_eq!(est.phi_deg, 120.0);
        let mut fresh = PoseEstimator::new(db).unwrap();
        fresh.respond(&index, Some(&mask), roi, est.scale);
        assert_eq!(refined.response(), fresh.response());
    }

    #[test]
    fn view_pairs_of_another_length_are_refused_and_matching_falls_back() {
        let rgb = painted(|_| true, 0);
        let mask = vec![255u8; 64 * 64];
        let views = [train::LabelledView::new(
            &rgb,
            &mask,
            (64, 64),
            (60.0, 0.0),
            1.0,
        )];
        let mut db =
            train::build_database("o", 1.0, &views, &train::TrainConfig::default()).unwrap();
        assert_eq!(view_pairs(&db).map(|p| p.len()), Some(1));
        store_view_pairs(&mut db, &[1.0, 2.0]);
        assert_eq!(view_pairs(&db), None);
        let e = PoseEstimator::new(db)
            .unwrap()
            .with_matching(Matching::Visible);
        assert_eq!(e.matching(), Matching::Normalised);
    }

    #[test]
    fn phi_error_wraps() {
        assert_eq!(phi_error(355.0, 5.0), 10.0);
        assert_eq!(phi_error(5.0, 355.0), 10.0);
        assert_eq!(phi_error(90.0, 270.0), 180.0);
        assert_eq!(phi_error(10.0, 10.0), 0.0);
    }

    #[test]
    fn the_trained_roll_search_is_recorded_and_zero_leaves_no_trace() {
        let pixels = [[10, 20, 30], [200, 100, 50]];
        let palette = acch_core::Palette::train(&pixels, 2, acch_core::ColourSpace::Lab, None, 1)
            .expect("palette");
        let params = acch_core::HistogramParams {
            colours: 2,
            ..Default::default()
        };
        let mut db = ViewDatabase::new("cube", palette, params, 1.0);
        assert_eq!(trained_roll_search_deg(&db), 0.0);
        store_roll_search_deg(&mut db, 45.0);
        assert_eq!(trained_roll_search_deg(&db), 45.0);
        let read = ViewDatabase::from_bytes(&db.to_bytes(), std::path::Path::new("x")).unwrap();
        assert_eq!(trained_roll_search_deg(&read), 45.0);
        store_roll_search_deg(&mut db, 0.0);
        assert!(db.sections.is_empty());
        // A section of the wrong size is not a search.
        db.sections.insert(ROLL_SEARCH_SECTION.into(), vec![1, 2]);
        assert_eq!(trained_roll_search_deg(&db), 0.0);
    }

    #[test]
    fn parabola_finds_the_peak() {
        // y = -(x - 53)^2 sampled at 45, 50, 60.
        let f = |x: f32| -(x - 53.0) * (x - 53.0);
        let v = parabola_vertex((45.0, f(45.0)), (50.0, f(50.0)), (60.0, f(60.0))).unwrap();
        assert!((v - 53.0).abs() < 1e-3, "{v}");
        // A minimum is no peak.
        assert!(parabola_vertex((0.0, 1.0), (1.0, 0.0), (2.0, 1.0)).is_none());
        // A vertex outside the points is still found (callers clamp it).
        let g = |x: f32| -(x - 70.0) * (x - 70.0);
        let v = parabola_vertex((40.0, g(40.0)), (50.0, g(50.0)), (60.0, g(60.0))).unwrap();
        assert!((v - 70.0).abs() < 1e-3, "{v}");
    }

    #[test]
    fn what_a_view_explains_is_the_share_mapped_times_the_match_value() {
        let stripes = |x: usize| x < 48;
        let a = painted(stripes, 0);
        let full = vec![255u8; 64 * 64];
        let config = train::TrainConfig {
            colours: 8,
            ..train::TrainConfig::default()
        };
        let views = [train::LabelledView::new(
            &a,
            &full,
            (64, 64),
            (60.0, 0.0),
            1.0,
        )];
        let db = train::build_database("o", 1.0, &views, &config).unwrap();
        let mut e = PoseEstimator::new(db.clone()).unwrap();
        let roi = Rect {
            x: 0,
            y: 0,
            width: 64,
            height: 64,
        };
        let mut index = db.palette.quantise(&a, 64, 64);
        let whole = e.explained(&index, &full, roi, Some(1.0)).unwrap();
        let value = |e: &mut PoseEstimator, index: &IndexImage| {
            e.estimate(
                index,
                Some(&full),
                roi,
                Some(1.0),
                Refinement::WinnerTakesAll,
            )
            .unwrap()
            .best_value
        };
        assert_eq!(whole, value(&mut e, &index));
        // A quarter of the pixels mapped to no colour, as under a light
        // that loses them: the share falls to three quarters.
        for px in index.data.iter_mut().step_by(4) {
            *px = acch_core::NOT_OBJECT;
        }
        let partly = e.explained(&index, &full, roi, Some(1.0)).unwrap();
        let v = value(&mut e, &index);
        assert!((partly - 0.75 * v).abs() < 1e-6, "{partly} vs {v}");
        // Nothing mapped: nothing to explain.
        index.data.fill(acch_core::NOT_OBJECT);
        assert_eq!(e.explained(&index, &full, roi, Some(1.0)), None);
    }
}
