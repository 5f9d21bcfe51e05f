//! Confidence: the database's network rates the pose stage's response; an
//! estimate is accepted only when it is rated at or above the threshold
//! and no view far from it in azimuth matches nearly as well (its rival at
//! most [`acch_confidence::MAX_RIVAL_RATIO`] of the best).
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

/// The verdict on one estimate.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Verdict {
    /// The network's probability that the estimate is within the failure
    /// thresholds.
    pub confidence: f32,
    /// The threshold it was held against.
    pub threshold: f32,
    /// The best match beyond 20° of the estimate's azimuth over the best
    /// ([`acch_confidence::rival_ratio`]).
    pub rival: f32,
    /// The largest rival accepted.
    pub max_rival: f32,
    /// `confidence >= threshold` and `rival <= max_rival` (NaN in either
    /// is rejected).
    pub accepted: bool,
}

impl Verdict {
    /// The verdict on `confidence` against `threshold` and on `rival`
    /// against `max_rival`.
    pub fn new(confidence: f32, threshold: f32, rival: f32, max_rival: f32) -> Self {
        Verdict {
            confidence,
            threshold,
            rival,
            max_rival,
            accepted: confidence >= threshold && rival <= max_rival,
        }
    }

    /// Whether a far view matched too nearly as well (rejected for it,
    /// whatever the confidence).
    pub fn ambiguous(&self) -> bool {
        use std::cmp::Ordering::{Equal, Less};
        // A NaN rival is ambiguous too.
        !matches!(self.rival.partial_cmp(&self.max_rival), Some(Less | Equal))
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
    /// Whether the estimate is accepted: rated, at or above the threshold.
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
        }
    }

    /// Accepts estimates whose rival is at most `max_rival` of the best
    /// match instead of [`acch_confidence::MAX_RIVAL_RATIO`] (1 accepts
    /// every rival: the network alone decides); to measure another bar.
    pub fn accept_rivals_to(&mut self, max_rival: f32) {
        self.max_rival = max_rival;
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
        )
        .map_err(|_| Fault::Response)?;
        Ok(Rating::Rated(Verdict::new(
            confidence,
            model.threshold(),
            rival,
            self.max_rival,
        )))
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

    #[test]
    fn only_a_rating_at_or_above_the_threshold_without_a_close_rival_is_accepted() {
        let verdict = |confidence, rival| Verdict::new(confidence, 0.8, rival, 0.99);
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
            Rating::Rated(Verdict::new(0.1, 0.8, 0.5, 0.99)).state(),
            "rejected"
        );
        assert_eq!(Rating::Unrated.state(), "unrated");
    }
}
