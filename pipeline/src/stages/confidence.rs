//! Confidence: judges each estimate by one policy over its evidence
//! ([`Verdict::new`]).
//!
//! An estimate the object's shape chose (the pose stage fitted the
//! mesh's contour to the image) is accepted only when its contour lies on
//! the region's edge ([`acch_confidence::MIN_REGION_EDGE`]), its
//! silhouette covers the region ([`acch_confidence::MIN_OVERLAP`]), it
//! explains the image clearly better than its rival
//! ([`acch_confidence::MIN_SHAPE_MARGIN`]), its contour lies in the frame
//! for a region recognition found ([`acch_confidence::MIN_IN_FRAME`]),
//! its elevation is at most [`acch_confidence::BELOW_LOWEST_VIEW_DEG`]
//! below the database's lowest view, it lies at most
//! [`acch_confidence::MAX_DISTANCE_RATIO`] times as far as the database
//! was trained for (or as the arm reports, when it does), and the object
//! was found at or above recognition's threshold. Geometry decides on real
//! photographs, where the colour rules below accepted 90 % wrong.
//!
//! An unverified estimate (a database without a shape, or a frame whose
//! pixels did not reach the pose stage) is judged by the colour
//! histograms' response as before: rated by the database's network at or
//! above its threshold, no view far from it matching nearly as well (its
//! rival at most [`acch_confidence::MAX_RIVAL_RATIO`] of the best), no
//! broad crest in azimuth (its plateau under
//! [`acch_confidence::PHI_PLATEAU_LIMIT_DEG`]), no view beyond the
//! tolerance holding the region's colours in place clearly better (its map
//! rival at most [`acch_confidence::MAX_MAP_RIVAL`]), and not found under
//! recognition's threshold, nor both faintly detected and weakly matched
//! ([`acch_confidence::rejected_as_faint`]).
//!
//! A database with neither a network nor a shape is refused unless the run
//! is explicitly unrated ([`StageSettings::unrated`]): then every estimate
//! is marked [`Rating::Unrated`], and nothing is accepted.

use super::BuildError;
use super::pose::{Posed, ResponsePayload};
use crate::config::StageSettings;
use crate::stage::Stage;
use crate::wire::{Envelope, Fault, Hop, StageId};
use acch_confidence::Model;
use acch_core::{View, ViewDatabase};
use acch_ipc::ZeroCopySend;
use acch_pose::Slice;

/// What an estimate is judged by.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Evidence {
    /// The network's probability that the estimate is within the failure
    /// thresholds.
    pub confidence: f32,
    /// The best match beyond 20° of the estimate's azimuth or 10° of its
    /// elevation over the best
    /// ([`acch_confidence::rival_ratio`]).
    pub rival: f32,
    /// The span in azimuth of the views about the estimate that match
    /// nearly as well, degrees ([`acch_confidence::phi_plateau_deg`]).
    pub phi_plateau_deg: f32,
    /// How much more of the region's coloured area a view beyond the
    /// tolerance holds in place than the estimate's
    /// ([`acch_pose::PoseEstimator::map_rival`]; `-inf`: none
    /// weighed).
    pub map_rival: f32,
    /// Recognition's score for the object's window over its threshold;
    /// infinity for a region recognition did not find (a given mask).
    pub detection_margin: f32,
    /// The best view's match value.
    pub match_value: f32,
    /// What the object's shape, fitted to the image, explains of it; `None`
    /// when the pose stage had no shape to fit (a database without one, a
    /// frame without pixels).
    pub shape: Option<ShapeEvidence>,
}

/// What the shape's fit explains of the image ([`crate::stages::ShapeFit`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeEvidence {
    /// Share of the fitted contour on the region's edge.
    pub region_edge: f32,
    /// The fitted silhouette against the region, intersection over union.
    pub overlap: f32,
    /// The fit's score over the best score of a candidate that would fail
    /// as an estimate of it (infinity: none did).
    pub margin: f32,
    /// The estimate's distance from the camera to the object's centre,
    /// metres (the seed's: after the blend).
    pub distance_m: f32,
    /// Share of the fitted contour in the frame.
    pub in_frame: f32,
    /// The estimate's elevation, degrees.
    pub theta_deg: f32,
    /// The colour histograms' view is the estimate and the fit placed it
    /// ([`crate::stages::ShapeFit::anchored`]).
    pub anchored: bool,
}

/// The verdict on one estimate.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Verdict {
    /// The network's probability that the estimate is within the failure
    /// thresholds.
    pub confidence: f32,
    /// The threshold it was held against.
    pub threshold: f32,
    /// The best match beyond 20° of the estimate's azimuth or 10° of its
    /// elevation over the best
    /// ([`acch_confidence::rival_ratio`]).
    pub rival: f32,
    /// The largest rival accepted.
    pub max_rival: f32,
    /// The span in azimuth of the views about the estimate that match
    /// within [`acch_confidence::PLATEAU_RATIO`] of it, degrees.
    pub phi_plateau_deg: f32,
    /// A plateau this broad or broader is rejected
    /// ([`acch_confidence::PHI_PLATEAU_LIMIT_DEG`]).
    pub phi_plateau_limit_deg: f32,
    /// How much more of the region's coloured area a view beyond the
    /// tolerance holds in place than the estimate's (`-inf`: none
    /// weighed).
    pub map_rival: f32,
    /// The largest map rival accepted
    /// ([`acch_confidence::MAX_MAP_RIVAL`]).
    pub max_map_rival: f32,
    /// Recognition's score over its threshold (infinity: a given mask).
    pub detection_margin: f32,
    /// The best view's match value.
    pub match_value: f32,
    /// 1 when the object's shape chose the estimate and verified it against
    /// the image (the shape's rules then decide); 2 when the colours placed
    /// it and the shape fitted it (the colour rules decide, and the contour
    /// must lie on the region's edge); 0 when no shape was fitted.
    pub verified: u32,
    /// Share of the fitted contour on the region's edge (NaN: unverified).
    pub region_edge: f32,
    /// The least share accepted ([`acch_confidence::MIN_REGION_EDGE`]).
    pub min_region_edge: f32,
    /// The fitted object's distance, metres (NaN: unverified).
    pub distance_m: f32,
    /// The farthest accepted for a pose the shape chose
    /// ([`acch_confidence::MAX_DISTANCE_RATIO`] times the distance the
    /// database was trained for, or the arm reports; infinity: unknown).
    pub max_distance_m: f32,
    /// The fitted silhouette against the region, intersection over union
    /// (NaN: unverified).
    pub overlap: f32,
    /// The least overlap accepted ([`acch_confidence::MIN_OVERLAP`]).
    pub min_overlap: f32,
    /// The fit's score over its rival's ([`acch_shape::ShapeEstimate::rival`];
    /// NaN: unverified).
    pub shape_margin: f32,
    /// The least margin accepted ([`acch_confidence::MIN_SHAPE_MARGIN`]).
    pub min_shape_margin: f32,
    /// Share of the fitted contour in the frame (NaN: unverified).
    pub in_frame: f32,
    /// The least share accepted for a region recognition found
    /// ([`acch_confidence::MIN_IN_FRAME`]).
    pub min_in_frame: f32,
    /// The estimate's elevation, degrees (NaN: unverified).
    pub theta_deg: f32,
    /// The lowest elevation accepted: the database's lowest view less
    /// [`acch_confidence::BELOW_LOWEST_VIEW_DEG`].
    pub min_theta_deg: f32,
    /// Chosen by the shape (verified 1): the contour on the region's edge
    /// and the silhouette covering the region, a clear margin over its
    /// rival ([`acch_shape::ShapeEstimate::rival`]), the contour in the frame (a region recognition
    /// found), the view no lower than the database covers, the object no
    /// farther than its bar, and found at or above recognition's
    /// threshold. Otherwise
    /// the colour rules: `confidence >= threshold`, `rival <= max_rival` (NaN in either is
    /// rejected), not [`broad`](Self::broad), not
    /// [`misplaced`](Self::misplaced) and not [`faint`](Self::faint); and
    /// when fitted (verified 2), the contour on the region's edge too (a
    /// region segmentation grew over part of the object is common there,
    /// and the colours vouch for the view).
    pub accepted: bool,
}

impl Verdict {
    /// The verdict on `evidence` by `rules`: its confidence against the
    /// threshold, its rival, plateau and map rival against their
    /// bars, its detection margin and match value against
    /// [`acch_confidence::rejected_as_faint`].
    pub fn new(evidence: Evidence, rules: Rules) -> Self {
        let mut v = Verdict {
            confidence: evidence.confidence,
            threshold: rules.threshold,
            rival: evidence.rival,
            max_rival: rules.max_rival,
            phi_plateau_deg: evidence.phi_plateau_deg,
            phi_plateau_limit_deg: rules.phi_plateau_limit_deg,
            map_rival: evidence.map_rival,
            max_map_rival: rules.max_map_rival,
            detection_margin: evidence.detection_margin,
            match_value: evidence.match_value,
            verified: match evidence.shape {
                None => 0,
                Some(s) if s.anchored => 2,
                Some(_) => 1,
            },
            region_edge: evidence.shape.map_or(f32::NAN, |s| s.region_edge),
            min_region_edge: rules.min_region_edge,
            distance_m: evidence.shape.map_or(f32::NAN, |s| s.distance_m),
            max_distance_m: rules.max_distance_m,
            overlap: evidence.shape.map_or(f32::NAN, |s| s.overlap),
            min_overlap: rules.min_overlap,
            shape_margin: evidence.shape.map_or(f32::NAN, |s| s.margin),
            min_shape_margin: rules.min_shape_margin,
            in_frame: evidence.shape.map_or(f32::NAN, |s| s.in_frame),
            min_in_frame: rules.min_in_frame,
            theta_deg: evidence.shape.map_or(f32::NAN, |s| s.theta_deg),
            min_theta_deg: rules.min_theta_deg,
            accepted: false,
        };
        let colour_rules = evidence.confidence >= rules.threshold
            && !v.ambiguous()
            && !v.broad()
            && !v.misplaced()
            && !v.faint();
        v.accepted = match v.verified {
            1 => {
                v.shape_agrees()
                    && v.shape_covers()
                    && v.shape_clear()
                    && v.shape_in_frame()
                    && v.shape_in_range()
                    && v.shape_near()
                    && !v.under_threshold()
            }
            2 => colour_rules && v.shape_agrees(),
            _ => colour_rules,
        };
        v
    }

    /// Whether the fitted contour lies on the region's edge (NaN: no).
    pub fn shape_agrees(&self) -> bool {
        self.region_edge >= self.min_region_edge
    }

    /// Whether the fit places the object no farther than its bar (NaN:
    /// no): a fragment fitted as a whole lands far behind it.
    pub fn shape_near(&self) -> bool {
        self.distance_m <= self.max_distance_m
    }

    /// Whether the fitted silhouette and the region cover each other
    /// (NaN: no): a contour can follow the edge of part of a larger
    /// region.
    pub fn shape_covers(&self) -> bool {
        self.overlap >= self.min_overlap
    }

    /// Whether enough of the fitted contour lies in the frame to judge it
    /// (NaN: no). A given mask (no detection: an infinite margin) vouches
    /// for the object however much of it the frame cuts.
    pub fn shape_in_frame(&self) -> bool {
        self.detection_margin == f32::INFINITY || self.in_frame >= self.min_in_frame
    }

    /// Whether the estimate's elevation reaches the bar: the database's
    /// lowest view less [`acch_confidence::BELOW_LOWEST_VIEW_DEG`] (NaN:
    /// no).
    pub fn shape_in_range(&self) -> bool {
        self.theta_deg >= self.min_theta_deg
    }

    /// Whether the fit beats every rival clearly (NaN: no).
    pub fn shape_clear(&self) -> bool {
        self.shape_margin >= self.min_shape_margin
    }

    /// Whether recognition found the object under its threshold (a window
    /// from 0.7x of it is still estimated, never accepted).
    pub fn under_threshold(&self) -> bool {
        !matches!(
            self.detection_margin
                .partial_cmp(&acch_confidence::MIN_ACCEPTED_DETECTION_MARGIN),
            Some(std::cmp::Ordering::Greater | std::cmp::Ordering::Equal)
        )
    }

    /// Whether a far view matched too nearly as well (rejected for it,
    /// whatever the confidence).
    pub fn ambiguous(&self) -> bool {
        use std::cmp::Ordering::{Equal, Less};
        // A NaN rival is ambiguous too.
        !matches!(self.rival.partial_cmp(&self.max_rival), Some(Less | Equal))
    }

    /// Whether the views about the estimate match nearly as well over a
    /// crest too broad to place it within the tolerance (rejected for it,
    /// whatever the confidence).
    pub fn broad(&self) -> bool {
        use std::cmp::Ordering::Less;
        // A NaN plateau is broad too.
        !matches!(
            self.phi_plateau_deg
                .partial_cmp(&self.phi_plateau_limit_deg),
            Some(Less)
        )
    }

    /// Whether a view beyond the tolerance holds the region's colours in
    /// place clearly better than the estimate's (rejected for it, whatever
    /// the confidence): the visible part lies where that view has it.
    pub fn misplaced(&self) -> bool {
        use std::cmp::Ordering::{Equal, Less};
        // A NaN rival (a region that could not be placed) is misplaced too.
        !matches!(
            self.map_rival.partial_cmp(&self.max_map_rival),
            Some(Less | Equal)
        )
    }

    /// Whether the object was found under recognition's threshold, or
    /// only faintly and matched weakly (rejected for it, whatever the
    /// confidence): it may not be in view.
    pub fn faint(&self) -> bool {
        acch_confidence::rejected_as_faint(self.detection_margin, self.match_value)
    }
}

/// The bars an estimate is held against.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rules {
    /// The network's rating must reach this.
    pub threshold: f32,
    /// The largest rival accepted ([`acch_confidence::MAX_RIVAL_RATIO`]).
    pub max_rival: f32,
    /// A plateau this broad or broader is rejected
    /// ([`acch_confidence::PHI_PLATEAU_LIMIT_DEG`]).
    pub phi_plateau_limit_deg: f32,
    /// The largest map rival accepted
    /// ([`acch_confidence::MAX_MAP_RIVAL`]).
    pub max_map_rival: f32,
    /// The least share of a verified contour on the region's edge.
    pub min_region_edge: f32,
    /// The farthest a pose the shape chose may place the object, metres.
    pub max_distance_m: f32,
    /// The least overlap of a verified silhouette with the region.
    pub min_overlap: f32,
    /// The least margin of a verified fit over its rival.
    pub min_shape_margin: f32,
    /// The least share of a verified contour in the frame, for a region
    /// recognition found.
    pub min_in_frame: f32,
    /// The lowest elevation of a verified estimate accepted, degrees.
    pub min_theta_deg: f32,
}

impl Rules {
    /// The default bars with the network's `threshold`, for a database
    /// whose lowest view and distance are unknown (any elevation and
    /// distance accepted).
    pub fn with_threshold(threshold: f32) -> Self {
        Rules {
            threshold,
            max_rival: acch_confidence::MAX_RIVAL_RATIO,
            phi_plateau_limit_deg: acch_confidence::PHI_PLATEAU_LIMIT_DEG,
            max_map_rival: acch_confidence::MAX_MAP_RIVAL,
            min_region_edge: acch_confidence::MIN_REGION_EDGE,
            max_distance_m: f32::INFINITY,
            min_overlap: acch_confidence::MIN_OVERLAP,
            min_shape_margin: acch_confidence::MIN_SHAPE_MARGIN,
            min_in_frame: acch_confidence::MIN_IN_FRAME,
            min_theta_deg: f32::NEG_INFINITY,
        }
    }
}

/// What the confidence stage made of an estimate.
#[repr(C, u32)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Rating {
    /// Nothing was estimated.
    #[default]
    Skipped,
    /// The run is unrated (its database has no network): not accepted.
    Unrated,
    /// Rated by the network.
    Rated(Verdict),
    /// The response could not be rated; counted, not accepted.
    Failed(Fault),
}

// SAFETY: repr(C, u32) over ZeroCopySend fields.
unsafe impl ZeroCopySend for Rating {}

impl From<Fault> for Rating {
    fn from(f: Fault) -> Self {
        Rating::Failed(f)
    }
}

impl Rating {
    /// Whether the estimate is accepted: rated, and its verdict accepted
    /// ([`Verdict::accepted`]).
    pub fn accepted(&self) -> bool {
        matches!(self, Rating::Rated(v) if v.accepted)
    }

    /// The verdict, when rated.
    pub fn verdict(&self) -> Option<Verdict> {
        match self {
            Rating::Rated(v) => Some(*v),
            _ => None,
        }
    }

    /// Its name in JSON and reports: skipped, unrated, accepted, rejected
    /// or failed.
    pub fn state(&self) -> &'static str {
        match self {
            Rating::Skipped => "skipped",
            Rating::Unrated => "unrated",
            Rating::Rated(v) if v.accepted => "accepted",
            Rating::Rated(_) => "rejected",
            Rating::Failed(_) => "failed",
        }
    }
}

/// Confidence's header.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Rated {
    /// Pose's header.
    pub posed: Posed,
    /// The verdict.
    pub rating: Rating,
}

impl Hop for Rated {
    fn envelope(&self) -> &Envelope {
        self.posed.envelope()
    }
    fn envelope_mut(&mut self) -> &mut Envelope {
        self.posed.envelope_mut()
    }
}

/// The confidence stage.
pub struct Confidence {
    /// `None`: the explicit unrated mode.
    model: Option<Model>,
    slices: Vec<Slice>,
    views: Vec<View>,
    response: Vec<f32>,
    max_rival: f32,
    phi_plateau_limit_deg: f32,
    max_map_rival: f32,
    /// Views farther than this in elevation from the best are rivals too.
    rival_theta_separation_deg: f32,
    min_region_edge: f32,
    min_overlap: f32,
    min_shape_margin: f32,
    min_in_frame: f32,
    /// The database's lowest view less
    /// [`acch_confidence::BELOW_LOWEST_VIEW_DEG`], degrees.
    min_theta_deg: f32,
    /// [`acch_confidence::MAX_DISTANCE_RATIO`] times the training distance
    /// (or the arm's), metres.
    max_distance_m: f32,
    /// The explicit unrated mode: nothing is accepted, even verified.
    unrated: bool,
}

impl Confidence {
    /// The stage for `db`: its network, or the unrated mode when the
    /// database has none and `settings.unrated` allows it.
    pub fn new(db: &ViewDatabase, settings: &StageSettings) -> Result<Self, BuildError> {
        let has_shape =
            settings.verify_shape && db.sections.contains_key(acch_shape::SHAPE_SECTION);
        let model = match Model::load(db) {
            Ok(m) => Some(m),
            // A database with a shape is judged by it without a network.
            Err(acch_confidence::ConfidenceError::MissingSection)
                if settings.unrated || has_shape =>
            {
                None
            }
            Err(acch_confidence::ConfidenceError::MissingSection) => {
                return Err(BuildError::NoConfidence {
                    object: db.object.clone(),
                });
            }
            Err(e) => return Err(e.into()),
        };
        let mut stage = Self::with_model(db, model);
        if let Some(d) = settings.distance_m {
            stage.max_distance_m = acch_confidence::MAX_DISTANCE_RATIO * d as f32;
        }
        // Nothing can judge: neither a network nor a shape.
        stage.unrated = stage.model.is_none() && !has_shape;
        Ok(stage)
    }

    /// The stage in the unrated mode, whatever the database holds (to
    /// collect the confidence network's own training data).
    pub fn unrated(db: &ViewDatabase) -> Self {
        let mut stage = Self::with_model(db, None);
        stage.unrated = true;
        stage
    }

    fn with_model(db: &ViewDatabase, model: Option<Model>) -> Self {
        Confidence {
            model,
            slices: acch_pose::slices(db),
            response: Vec::with_capacity(db.views().len()),
            views: db.views().to_vec(),
            max_rival: acch_confidence::MAX_RIVAL_RATIO,
            phi_plateau_limit_deg: acch_confidence::PHI_PLATEAU_LIMIT_DEG,
            max_map_rival: acch_confidence::MAX_MAP_RIVAL,
            rival_theta_separation_deg: acch_confidence::Tolerance::default().theta_deg,
            min_region_edge: acch_confidence::MIN_REGION_EDGE,
            min_overlap: acch_confidence::MIN_OVERLAP,
            min_shape_margin: acch_confidence::MIN_SHAPE_MARGIN,
            min_in_frame: acch_confidence::MIN_IN_FRAME,
            min_theta_deg: acch_confidence::min_theta_deg(db),
            max_distance_m: acch_confidence::MAX_DISTANCE_RATIO * db.train_distance_m,
            unrated: false,
        }
    }

    /// Counts as rivals only the views far in azimuth, not those beyond
    /// the failure tolerance in elevation ([`acch_confidence::rival_ratio`]
    /// with an infinite elevation separation); to measure the elevation
    /// side apart.
    pub fn rivals_in_azimuth_only(&mut self) {
        self.rival_theta_separation_deg = f32::INFINITY;
    }

    /// Accepts estimates whose rival is at most `max_rival` of the best
    /// match instead of [`acch_confidence::MAX_RIVAL_RATIO`] (1 accepts
    /// every rival: the network alone decides); to measure another bar.
    pub fn accept_rivals_to(&mut self, max_rival: f32) {
        self.max_rival = max_rival;
    }

    /// Rejects estimates on a crest in azimuth of `limit_deg` or more
    /// instead of [`acch_confidence::PHI_PLATEAU_LIMIT_DEG`] (infinity:
    /// no crest is too broad); to measure another limit, or the other
    /// rules without this one.
    pub fn reject_crests_from(&mut self, limit_deg: f32) {
        self.phi_plateau_limit_deg = limit_deg;
    }

    /// Accepts estimates whose map rival is at most `max` instead of
    /// [`acch_confidence::MAX_MAP_RIVAL`] (infinity: every
    /// map rival is accepted); to measure another bar, or the other rules
    /// without this one.
    pub fn accept_map_rivals_to(&mut self, max: f32) {
        self.max_map_rival = max;
    }

    /// The network, unless unrated.
    pub fn model(&self) -> Option<&Model> {
        self.model.as_ref()
    }

    /// The threshold estimates are held against (`None`: unrated).
    pub fn threshold(&self) -> Option<f32> {
        self.model.as_ref().map(Model::threshold)
    }
}

impl Stage for Confidence {
    const ID: StageId = StageId::Confidence;
    type Input = Posed;
    type Part = Rating;
    type Output = Rated;

    fn max_payload(&self) -> usize {
        0
    }

    fn process(
        &mut self,
        input: &Posed,
        payload: &[u8],
        _: &[u8],
        _: &mut [u8],
    ) -> Result<Rating, Fault> {
        let Some(response) = ResponsePayload::read(input, self.views.len(), payload)? else {
            return Ok(Rating::Skipped);
        };
        let pose = input.pose.done();
        let shape = pose
            .and_then(|p| p.shape.done().map(|f| (p, f)))
            .map(|(p, f)| ShapeEvidence {
                region_edge: f.region_edge,
                overlap: f.overlap,
                margin: f.score - f.rival_score,
                distance_m: glam::Vec3::from(f.translation_m).length(),
                in_frame: f.in_frame,
                theta_deg: p.theta_deg,
                anchored: f.anchored == 1,
            });
        // The shape judges what it chose; colours that placed the object
        // themselves (anchored) need the network too.
        let shape_judges = shape.is_some_and(|s| !s.anchored);
        if self.unrated || (self.model.is_none() && !shape_judges) {
            // Nothing that can judge this estimate: a database without a
            // network whose colours placed the object.
            return Ok(Rating::Unrated);
        }
        response.copy_into(&mut self.response);
        let (confidence, rival, phi_plateau_deg, threshold) = match &self.model {
            Some(model) => (
                model
                    .try_rate(&self.response, &self.slices, &self.views)
                    .map_err(|_| Fault::Response)?,
                acch_confidence::rival_ratio(
                    &self.response,
                    &self.views,
                    model.feature_params().min_phi_separation_deg,
                    self.rival_theta_separation_deg,
                )
                .map_err(|_| Fault::Response)?,
                acch_confidence::phi_plateau_deg(
                    &self.response,
                    &self.slices,
                    &self.views,
                    acch_confidence::PLATEAU_RATIO,
                )
                .map_err(|_| Fault::Response)?,
                model.threshold(),
            ),
            // No network: the shape alone judges.
            None => (f32::NAN, f32::NAN, f32::NAN, f32::NAN),
        };
        let evidence = Evidence {
            confidence,
            rival,
            phi_plateau_deg,
            map_rival: pose.map_or(f32::NAN, |p| p.map_rival),
            detection_margin: input
                .segmented
                .recognised
                .detection
                .done()
                .map_or(f32::INFINITY, |w| w.margin()),
            match_value: pose.map_or(f32::NAN, |p| p.best_value),
            shape,
        };
        let rules = Rules {
            threshold,
            max_rival: self.max_rival,
            phi_plateau_limit_deg: self.phi_plateau_limit_deg,
            max_map_rival: self.max_map_rival,
            min_region_edge: self.min_region_edge,
            max_distance_m: self.max_distance_m,
            min_overlap: self.min_overlap,
            min_shape_margin: self.min_shape_margin,
            min_in_frame: self.min_in_frame,
            min_theta_deg: self.min_theta_deg,
        };
        Ok(Rating::Rated(Verdict::new(evidence, rules)))
    }

    fn output(input: &Posed, rating: Rating) -> Rated {
        Rated {
            posed: *input,
            rating,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Evidence of a detection that was not judged faint.
    fn clear(confidence: f32, rival: f32) -> Evidence {
        Evidence {
            confidence,
            rival,
            phi_plateau_deg: 0.0,
            map_rival: -0.2,
            detection_margin: f32::INFINITY,
            match_value: 0.9,
            shape: None,
        }
    }

    /// The default bars at the paper's threshold.
    fn rules() -> Rules {
        Rules::with_threshold(0.8)
    }

    /// A fit the shape chose, 1 m away at 30° of elevation, its contour
    /// in the frame.
    fn fit(region_edge: f32, overlap: f32, margin: f32) -> ShapeEvidence {
        ShapeEvidence {
            region_edge,
            overlap,
            margin,
            distance_m: 1.0,
            in_frame: 1.0,
            theta_deg: 30.0,
            anchored: false,
        }
    }

    /// The verdict on `shape`, chosen by the shape, with no network.
    fn judged_by_shape(shape: ShapeEvidence, rules: Rules) -> Verdict {
        Verdict::new(
            Evidence {
                confidence: f32::NAN,
                rival: f32::NAN,
                shape: Some(shape),
                ..clear(f32::NAN, f32::NAN)
            },
            rules,
        )
    }

    #[test]
    fn a_pose_the_shape_chose_is_accepted_by_the_shapes_bars_alone() {
        // No network (NaN confidence) and no colour evidence: the shape's
        // evidence decides.
        let judged_in = |region_edge, overlap, margin, detection_margin, in_frame| {
            Verdict::new(
                Evidence {
                    confidence: f32::NAN,
                    rival: f32::NAN,
                    detection_margin,
                    shape: Some(ShapeEvidence {
                        in_frame,
                        ..fit(region_edge, overlap, margin)
                    }),
                    ..clear(f32::NAN, f32::NAN)
                },
                rules(),
            )
        };
        let judged = |region_edge, overlap, margin, detection_margin| {
            judged_in(region_edge, overlap, margin, detection_margin, 1.0)
        };
        let v = judged(0.95, 0.85, 0.5, f32::INFINITY);
        assert!(v.accepted && v.verified == 1, "{v:?}");
        assert!(judged(0.9, 0.7, 0.3, 1.0).accepted, "at every bar");
        assert!(judged(0.9, 0.7, f32::INFINITY, 1.0).accepted, "no rival");
        for (edge, overlap, margin, detection, why) in [
            (
                0.89,
                0.85,
                0.5,
                f32::INFINITY,
                "contour off the region's edge",
            ),
            (
                0.95,
                0.69,
                0.5,
                f32::INFINITY,
                "silhouette covers too little",
            ),
            (0.95, 0.85, 0.29, f32::INFINITY, "a rival explains as much"),
            (0.95, 0.85, 0.5, 0.99, "found under the threshold"),
            (f32::NAN, 0.85, 0.5, f32::INFINITY, "no edge measured"),
            (0.95, f32::NAN, 0.5, f32::INFINITY, "no overlap measured"),
            (0.95, 0.85, f32::NAN, f32::INFINITY, "no margin measured"),
        ] {
            let v = judged(edge, overlap, margin, detection);
            assert!(!v.accepted, "{why}: {v:?}");
        }
        // A region recognition found (a finite detection margin) is judged
        // only with its contour in the frame; a given mask whatever the
        // frame cuts of it.
        assert!(judged_in(0.95, 0.85, 0.5, 1.2, 0.98).accepted, "at the bar");
        let cut = judged_in(0.95, 0.85, 0.5, 1.2, 0.97);
        assert!(!cut.accepted && !cut.shape_in_frame(), "{cut:?}");
        assert!(
            !judged_in(0.95, 0.85, 0.5, 1.2, f32::NAN).accepted,
            "none measured"
        );
        assert!(
            judged_in(0.95, 0.85, 0.5, f32::INFINITY, 0.6).accepted,
            "a given mask"
        );
        // A view below what the database covers is no pose it vouches
        // for: its lowest view (20°) less 5° is the bar.
        let at = |theta_deg| {
            judged_by_shape(
                ShapeEvidence {
                    theta_deg,
                    ..fit(0.95, 0.85, 0.5)
                },
                Rules {
                    min_theta_deg: 20.0 - acch_confidence::BELOW_LOWEST_VIEW_DEG,
                    ..rules()
                },
            )
        };
        assert!(at(15.0).accepted && at(40.0).accepted, "{:?}", at(15.0));
        for theta_deg in [14.9, -15.0, f32::NAN] {
            let v = at(theta_deg);
            assert!(!v.accepted && !v.shape_in_range(), "{v:?}");
        }
        // Anchored by the colours: the colour rules and the shape's
        // agreement both, so no network rating means rejected.
        let anchored = |confidence| {
            Verdict::new(
                Evidence {
                    shape: Some(ShapeEvidence {
                        anchored: true,
                        ..fit(0.95, 0.85, f32::NAN)
                    }),
                    ..clear(confidence, 0.5)
                },
                rules(),
            )
        };
        assert!(anchored(0.9).accepted && anchored(0.9).verified == 2);
        // ...whose region may cover part of the object only.
        let partial = Verdict::new(
            Evidence {
                shape: Some(ShapeEvidence {
                    anchored: true,
                    ..fit(0.95, 0.6, f32::NAN)
                }),
                ..clear(0.9, 0.5)
            },
            rules(),
        );
        assert!(partial.accepted, "{partial:?}");
        assert!(!anchored(0.5).accepted && !anchored(f32::NAN).accepted);
    }

    #[test]
    fn a_pose_the_shape_chose_beyond_the_distance_bar_is_rejected() {
        // Trained at 0.5 m.
        let bar = acch_confidence::MAX_DISTANCE_RATIO * 0.5;
        let at = |distance_m| {
            judged_by_shape(
                ShapeEvidence {
                    distance_m,
                    ..fit(0.95, 0.85, 0.5)
                },
                Rules {
                    max_distance_m: bar,
                    ..rules()
                },
            )
        };
        assert!(at(bar).accepted && at(0.2).accepted, "{:?}", at(bar));
        for distance_m in [bar + 0.01, 3.0, f32::NAN] {
            let v = at(distance_m);
            assert!(!v.accepted && !v.shape_near(), "{v:?}");
        }
        // With no training distance known, any distance.
        let far = ShapeEvidence {
            distance_m: 30.0,
            ..fit(0.95, 0.85, 0.5)
        };
        let v = judged_by_shape(far, rules());
        assert!(v.accepted, "{v:?}");
    }

    #[test]
    fn only_a_rating_at_or_above_the_threshold_without_a_close_rival_is_accepted() {
        let verdict = |confidence, rival| Verdict::new(clear(confidence, rival), rules());
        assert!(Rating::Rated(verdict(0.8, 0.99)).accepted());
        assert!(!Rating::Rated(verdict(0.79, 0.5)).accepted());
        assert!(!Rating::Rated(verdict(f32::NAN, 0.5)).accepted());
        assert!(!Rating::Rated(verdict(1.0, 0.995)).accepted());
        assert!(!Rating::Rated(verdict(1.0, f32::NAN)).accepted());
        assert!(verdict(1.0, 0.995).ambiguous() && !verdict(0.5, 0.99).ambiguous());
        for r in [
            Rating::Skipped,
            Rating::Unrated,
            Rating::Failed(Fault::Response),
        ] {
            assert!(!r.accepted(), "{r:?}");
        }
        assert_eq!(
            Rating::Rated(Verdict::new(clear(0.1, 0.5), rules())).state(),
            "rejected"
        );
        assert_eq!(Rating::Unrated.state(), "unrated");
    }

    #[test]
    fn a_faint_detection_with_a_weak_match_is_rejected_whatever_its_rating() {
        let judged = |detection_margin, match_value| {
            Verdict::new(
                Evidence {
                    detection_margin,
                    match_value,
                    ..clear(1.0, 0.5)
                },
                rules(),
            )
        };
        let faint = judged(1.1, 0.5);
        assert!(
            faint.faint() && !faint.accepted && !faint.ambiguous(),
            "{faint:?}"
        );
        assert_eq!(Rating::Rated(faint).state(), "rejected");
        assert!(judged(1.1, 0.8).accepted, "a good match");
        assert!(judged(2.0, 0.5).accepted, "a clear detection");
        assert!(judged(f32::INFINITY, 0.3).accepted, "a given mask");
        assert!(!judged(1.1, f32::NAN).accepted, "no match value");
    }

    #[test]
    fn a_broad_crest_in_azimuth_is_rejected_whatever_its_rating() {
        let judged = |phi_plateau_deg| {
            Verdict::new(
                Evidence {
                    phi_plateau_deg,
                    ..clear(1.0, 0.5)
                },
                rules(),
            )
        };
        for narrow in [0.0, 30.0, 39.9] {
            let v = judged(narrow);
            assert!(v.accepted && !v.broad(), "{v:?}");
        }
        for broad in [40.0, 360.0, f32::NAN] {
            let v = judged(broad);
            assert!(
                v.broad() && !v.accepted && !v.ambiguous() && !v.faint(),
                "{v:?}"
            );
            assert_eq!(Rating::Rated(v).state(), "rejected");
        }
    }

    #[test]
    fn an_estimate_another_view_places_clearly_better_is_rejected_whatever_its_rating() {
        let judged = |map_rival| {
            Verdict::new(
                Evidence {
                    map_rival,
                    ..clear(1.0, 0.5)
                },
                rules(),
            )
        };
        // At or under the bar, and with nothing weighed (-inf), accepted.
        for placed in [f32::NEG_INFINITY, -0.3, 0.0, 0.02] {
            let v = judged(placed);
            assert!(v.accepted && !v.misplaced(), "{v:?}");
        }
        for misplaced in [0.0201, 0.5, f32::INFINITY, f32::NAN] {
            let v = judged(misplaced);
            assert!(
                v.misplaced() && !v.accepted && !v.ambiguous() && !v.broad() && !v.faint(),
                "{v:?}"
            );
            assert_eq!(Rating::Rated(v).state(), "rejected");
        }
    }
}
