//! Confidence: the database's network rates the pose stage's response; an
//! estimate is accepted only when it is rated at or above the threshold,
//! no view far from it in azimuth matches nearly as well (its rival at
//! most [`acch_confidence::MAX_RIVAL_RATIO`] of the best), the views about
//! it do not match nearly as well over a broad crest in azimuth (their
//! plateau under [`acch_confidence::PHI_PLATEAU_LIMIT_DEG`]), no view
//! beyond the tolerance holds the region's colours in place clearly
//! better (its map rival at most
//! [`acch_confidence::MAX_MAP_RIVAL`]), and it was not found under
//! recognition's threshold, nor both faintly detected and weakly matched
//! ([`acch_confidence::rejected_as_faint`]).
//!
//! A database without a network is refused unless the run is explicitly
//! unrated ([`StageSettings::unrated`]): then every estimate is marked
//! [`Rating::Unrated`], and nothing is accepted.

use super::pose::{Posed, ResponsePayload};
use super::{BuildError, StageSettings};
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
    /// `confidence >= threshold`, `rival <= max_rival` (NaN in either is
    /// rejected), not [`broad`](Self::broad), not
    /// [`misplaced`](Self::misplaced) and not [`faint`](Self::faint).
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
            accepted: false,
        };
        v.accepted = evidence.confidence >= rules.threshold
            && !v.ambiguous()
            && !v.broad()
            && !v.misplaced()
            && !v.faint();
        v
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
}

impl Rules {
    /// The default bars with the network's `threshold`.
    pub fn with_threshold(threshold: f32) -> Self {
        Rules {
            threshold,
            max_rival: acch_confidence::MAX_RIVAL_RATIO,
            phi_plateau_limit_deg: acch_confidence::PHI_PLATEAU_LIMIT_DEG,
            max_map_rival: acch_confidence::MAX_MAP_RIVAL,
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
}

impl Confidence {
    /// The stage for `db`: its network, or the unrated mode when the
    /// database has none and `settings.unrated` allows it.
    pub fn new(db: &ViewDatabase, settings: &StageSettings) -> Result<Self, BuildError> {
        let model = match Model::load(db) {
            Ok(m) => Some(m),
            Err(acch_confidence::ConfidenceError::MissingSection) if settings.unrated => None,
            Err(acch_confidence::ConfidenceError::MissingSection) => {
                return Err(BuildError::NoConfidence {
                    object: db.object.clone(),
                });
            }
            Err(e) => return Err(e.into()),
        };
        Ok(Self::with_model(db, model))
    }

    /// The stage in the unrated mode, whatever the database holds (to
    /// collect the confidence network's own training data).
    pub fn unrated(db: &ViewDatabase) -> Self {
        Self::with_model(db, None)
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

    fn process(&mut self, input: &Posed, payload: &[u8], _: &mut [u8]) -> Result<Rating, Fault> {
        let Some(response) = ResponsePayload::read(input, self.views.len(), payload)? else {
            return Ok(Rating::Skipped);
        };
        let Some(model) = &self.model else {
            return Ok(Rating::Unrated);
        };
        response.copy_into(&mut self.response);
        let confidence = model
            .try_rate(&self.response, &self.slices, &self.views)
            .map_err(|_| Fault::Response)?;
        let rival = acch_confidence::rival_ratio(
            &self.response,
            &self.views,
            model.feature_params().min_phi_separation_deg,
            self.rival_theta_separation_deg,
        )
        .map_err(|_| Fault::Response)?;
        let phi_plateau_deg = acch_confidence::phi_plateau_deg(
            &self.response,
            &self.slices,
            &self.views,
            acch_confidence::PLATEAU_RATIO,
        )
        .map_err(|_| Fault::Response)?;
        let pose = input.pose.done();
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
        };
        let rules = Rules {
            threshold: model.threshold(),
            max_rival: self.max_rival,
            phi_plateau_limit_deg: self.phi_plateau_limit_deg,
            max_map_rival: self.max_map_rival,
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
        }
    }

    /// The default bars at the paper's threshold.
    fn rules() -> Rules {
        Rules::with_threshold(0.8)
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
