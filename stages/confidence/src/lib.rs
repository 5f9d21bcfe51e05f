//! Confidence rating of a 2-DOF estimate from its match-value response
//! (paper, section 4).
//!
//! An estimate read off an ambiguous response — several local maxima of
//! similar height, in φ within the best elevation or across elevations — is
//! likely wrong. A small feed-forward network turns the response into the
//! probability `h(x)` that the estimate is reliable; the pipeline rejects
//! it below a threshold ([`DEFAULT_THRESHOLD`] = 0.8, as in the paper).
//!
//! * [`features`]: the four features R_φ, D_φ, R_θ, D_θ (with their exact
//!   definitions) and the normalised response.
//! * [`Model`]: the network (standardised inputs, one tanh hidden layer,
//!   sigmoid output) of either [`Kind`], trained with [`train`] by
//!   full-batch Adam on the cross-entropy of eq. 3; [`Model::rate`] is the
//!   allocation-free per-frame call; [`Model::to_bytes`] /
//!   [`Model::from_bytes`] are the format of the database's
//!   `"confidence"` section ([`SECTION`]).
//! * [`eval`]: ROC AUC, reliability bins and acceptance statistics.
//! * [`Tolerance`]: the ground-truth label of an estimate (failure =
//!   |Δθ| > 10° or |Δφ| > 20°).

#![warn(missing_docs)]

pub mod eval;
pub mod features;
mod model;
mod network;

pub use eval::{Acceptance, Bin, expected_calibration_error, reliability_bins, roc_auc};
pub use features::{
    DEFAULT_MIN_PHI_SEPARATION_DEG, FEATURE_COUNT, FeatureParams, Features, ResponseFeatures,
    normalise_into, phi_plateau_deg, rival_ratio,
};
pub use model::{
    ClassWeighting, Kind, MAX_HIDDEN, MODEL_FORMAT_VERSION, Model, TrainConfig, train,
    train_with_progress,
};

/// The paper's acceptance threshold: estimates rated below 0.8 are
/// rejected.
pub const DEFAULT_THRESHOLD: f32 = 0.8;

/// An estimate is rejected, whatever the network says, when a view more
/// than [`DEFAULT_MIN_PHI_SEPARATION_DEG`] away in azimuth, or more than
/// the failure tolerance ([`Tolerance`], 10°) in elevation, matches above
/// this share of the best ([`rival_ratio`]): two poses that far apart
/// match as well, and which one is right is a coin's toss. Seen from near
/// above, a box or a bottle often looks so (docs/accuracy.md, "Two views
/// that match as well"); the network, trained on few such scenes, accepted
/// them.
pub const MAX_RIVAL_RATIO: f32 = 0.99;

/// The share of the best match the views about it must reach to extend
/// its plateau in azimuth ([`phi_plateau_deg`]).
pub const PLATEAU_RATIO: f32 = 0.98;

/// An estimate is rejected, whatever the network says, when the views
/// about it in its θ slice that match within [`PLATEAU_RATIO`] of the best
/// span this many degrees of azimuth or more ([`phi_plateau_deg`]): twice
/// the 20° failure tolerance, so the truth may lie farther from the
/// estimate than the tolerance and the response cannot say. Seen from the
/// side, a blurred or partly hidden object often matches so over a broad
/// crest (docs/accuracy.md, "A broad crest in azimuth"); the rival, which
/// looks only beyond 20°, and the network missed those.
pub const PHI_PLATEAU_LIMIT_DEG: f32 = 40.0;

/// An estimate is rejected, whatever the network says, when a view of its
/// θ slice 20-60° from it in azimuth holds its region's colours in place
/// (on the views' colour maps) by more than this share of their area
/// better than its own view does (the pose stage's map rival,
/// `acch_pose::PoseEstimator::map_rival`): the visible part lies where
/// that view has it, beyond the tolerance. An occluder that hides the side
/// telling a view from its neighbours leaves near misses the response and
/// the network are sure of (docs/accuracy.md, "Where the visible part
/// lies"). Chosen on the robust protocol's two development seeds: right
/// estimates of occluded objects reach it in about 1 % of frames.
pub const MAX_MAP_RIVAL: f32 = 0.02;

/// An estimate the object's shape verified is accepted only when this
/// share of its fitted contour or more lies on the region's edge (the
/// region inside the contour, not outside it): the silhouette and the
/// region agree. On LM-O's real photographs, with the annotated mask,
/// right estimates reach a median of 0.89-0.99 by it and wrong ones
/// 0.51-0.87 (docs/accuracy.md, "Real photographs").
pub const MIN_REGION_EDGE: f32 = 0.9;

/// ...and, when the shape alone chose it (the colours did not anchor the
/// view), only when its silhouette and the region cover each other by at
/// least this intersection over union: a contour can follow the edge of
/// part of a larger region. (Anchored estimates are exempt: there a
/// region grown over part of the object is common, 0.62-0.68 on rendered
/// frames of the fruitbox whose colours place the view right.) On LM-O's development objects, right accepted
/// estimates reach 0.72 or more with the annotated mask; the one wrong
/// estimate automatic segmentation accepted without it covered 0.54 of a
/// region off the object (docs/real-photographs.md).
pub const MIN_OVERLAP: f32 = 0.7;

/// ...and, when recognition and segmentation found the region (not a mask
/// given with the frame), only when at least this share of its fitted
/// contour falls in the frame: the frame's border cuts a region of
/// anything, and a silhouette reaching beyond it is judged on the part
/// left, which fits too much. On LM-O's development objects with
/// automatic segmentation (the region refined by the frame's colours) the
/// one wrong estimate accepted without this bar was the glue fitted to a
/// blob at the frame's left edge, a third of its contour beyond it; right
/// accepted estimates with the annotated mask reach 0.64-1.
pub const MIN_IN_FRAME: f32 = 0.98;

/// ...and only when its elevation lies at most this many degrees below
/// the lowest view the database was trained for: the database covers the
/// elevations the camera sees, so a view below them is no pose it can
/// vouch for. On LM-O's development objects with the annotated mask, the
/// wrong estimates this removed were the glue seen from below its
/// horizontal plane where the camera looked from above (the two outlines
/// are mirror images); no right accepted estimate lay below the lowest
/// view (docs/real-photographs.md, "Sixth round"). Half the failure
/// tolerance in elevation leaves room for a right fit just under the
/// lowest view.
pub const BELOW_LOWEST_VIEW_DEG: f32 = 5.0;

/// The lowest elevation a pose of `db`'s object is accepted at: its lowest
/// view less [`BELOW_LOWEST_VIEW_DEG`] (-inf for a database without
/// views: no range is known). The shape takes it as the lowest elevation
/// the camera sees (`acch_shape::ShapeSettings::lowest_elevation_deg`):
/// a pose below it is no answer and no rival.
pub fn min_theta_deg(db: &acch_core::ViewDatabase) -> f32 {
    db.theta_range_deg()
        .map_or(f32::NEG_INFINITY, |(lowest, _)| {
            lowest - BELOW_LOWEST_VIEW_DEG
        })
}

/// ...and only when its fit places the object at most this many times
/// as far as the database was trained for (or as the arm reports, when
/// it does): recognition's window is sized for that distance, and a
/// fragment fitted as a whole lands far behind the object. On LM-O's
/// development objects with the annotated mask, it rejected a glue
/// fitted 1.9 times the training distance away, 33° off (and, in a
/// variant not kept, an ape 18 % visible fitted 2.2 times, 111° off);
/// right accepted estimates lay at most 1.33 times as far, and the robust
/// protocol takes rendered objects to 1.5 times
/// (docs/real-photographs.md, "Eighth round").
pub const MAX_DISTANCE_RATIO: f32 = 1.6;

/// ...and only when its score (what it explains of the image) beats the
/// best candidate that would be a failure if it were right, the object's
/// symmetries allowed for, and that the camera sees (not below
/// [`min_theta_deg`]), by this much: another pose that explains the
/// image about as well makes it a guess. A candidate within
/// `acch_shape::ShapeSettings::rival_span` failure tolerances of it is no
/// such rival: as good and that near, it says the truth lies between the
/// two.
pub const MIN_SHAPE_MARGIN: f32 = 0.3;

/// A detection under recognition's threshold (its margin below this) is
/// found, and never accepted ([`rejected_as_faint`]): recognition finds a
/// window from 0.7x of its threshold (`acch_recognition::MIN_FOUND_MARGIN`)
/// so that a half-hidden object is still estimated, but an estimate the threshold
/// alone would have called "not found" is not one to grasp on (on a draw of
/// the evaluation objects 2 of 8 such estimates the network accepted were
/// wrong: docs/accuracy.md, "Found down to 0.7x the threshold").
pub const MIN_ACCEPTED_DETECTION_MARGIN: f32 = 1.0;

/// A detection that clears recognition's threshold by less than this
/// factor is faint ([`rejected_as_faint`]).
pub const MIN_CLEAR_DETECTION_MARGIN: f32 = 1.3;

/// A best match value below this is weak ([`rejected_as_faint`]).
pub const MIN_CLEAR_MATCH_VALUE: f32 = 0.75;

/// Whether an estimate is rejected, whatever the network says, because
/// recognition found its object only faintly: under its threshold
/// (`detection_margin`, the window's score over its threshold, below
/// [`MIN_ACCEPTED_DETECTION_MARGIN`]), or below
/// [`MIN_CLEAR_DETECTION_MARGIN`] with no view matching it well
/// (`match_value` below [`MIN_CLEAR_MATCH_VALUE`]). An object that is not
/// in view at all, found on another object or on the table, looks so; the
/// network, which reads the response's shape, rates such estimates 0.999
/// (docs/multi.md, "An object not in view"). A region not found by
/// recognition (a given mask) has no margin: pass infinity. A match value
/// that is not a number is weak.
pub fn rejected_as_faint(detection_margin: f32, match_value: f32) -> bool {
    // A NaN match value is weak too.
    let clear_match = matches!(
        match_value.partial_cmp(&MIN_CLEAR_MATCH_VALUE),
        Some(std::cmp::Ordering::Greater | std::cmp::Ordering::Equal)
    );
    detection_margin < MIN_ACCEPTED_DETECTION_MARGIN
        || (detection_margin < MIN_CLEAR_DETECTION_MARGIN && !clear_match)
}

/// Name of the view-database section that holds the model.
pub const SECTION: &str = "confidence";

/// Why a response could not be rated, a model trained or loaded.
#[derive(Debug, thiserror::Error)]
pub enum ConfidenceError {
    /// The response has no values.
    #[error("the match-value response is empty")]
    EmptyResponse,
    /// A match value is negative or not a finite number.
    #[error("match value {index} is {value}: expected a finite, non-negative number")]
    InvalidResponse {
        /// Index of the view.
        index: usize,
        /// The value.
        value: f32,
    },
    /// Two inputs that must have the same length do not.
    #[error("{what} has {found} entries, the response has {expected}")]
    LengthMismatch {
        /// Which input.
        what: &'static str,
        /// The response length.
        expected: usize,
        /// The input's length.
        found: usize,
    },
    /// A view used by the features has a non-finite azimuth.
    #[error("view {index} has a non-finite azimuth")]
    InvalidView {
        /// Index of the view.
        index: usize,
    },
    /// The slices do not split the response into runs.
    #[error("invalid θ slices: {0}")]
    BadSlices(&'static str),
    /// The network expects another number of inputs.
    #[error("the model has {expected} inputs but was given {found}")]
    InputSize {
        /// The model's inputs.
        expected: usize,
        /// Inputs given.
        found: usize,
    },
    /// A setting is out of range.
    #[error("invalid confidence setting: {0}")]
    InvalidConfig(String),
    /// Training was given no samples.
    #[error("no training samples")]
    NoSamples,
    /// A training sample is unusable.
    #[error("training sample {index}: {reason}")]
    InvalidSample {
        /// Index of the sample.
        index: usize,
        /// What is wrong.
        reason: String,
    },
    /// The training set has only one class.
    #[error(
        "training needs reliable and unreliable examples, got {reliable} reliable and {unreliable} unreliable"
    )]
    OneClass {
        /// Reliable examples.
        reliable: usize,
        /// Unreliable examples.
        unreliable: usize,
    },
    /// The optimisation produced non-finite weights (learning rate too
    /// high).
    #[error("training diverged (non-finite weights); lower the learning rate")]
    Diverged,
    /// The database has no confidence section.
    #[error("the database has no '{SECTION}' section; train a confidence model first")]
    MissingSection,
    /// The bytes are not a confidence model.
    #[error("not a confidence model (bad magic bytes)")]
    BadMagic,
    /// Written by another format version.
    #[error(
        "confidence model format version {found} is not supported (this build reads version {supported}); retrain it"
    )]
    UnsupportedVersion {
        /// Version in the bytes.
        found: u32,
        /// Version this build reads.
        supported: u32,
    },
    /// The bytes end early.
    #[error("confidence model truncated: expected {expected} bytes, found {found}")]
    Truncated {
        /// Bytes needed.
        expected: usize,
        /// Bytes present.
        found: usize,
    },
    /// The bytes are inconsistent.
    #[error("corrupt confidence model: {0}")]
    Corrupt(String),
}

/// The verdict on one estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rating {
    /// Probability that the estimate is reliable, in [0, 1].
    pub confidence: f32,
    /// Whether it reaches the threshold.
    pub accepted: bool,
}

impl Rating {
    /// Accepts `confidence` when it is at least `threshold` (the paper
    /// rejects h(x) < 0.8). A NaN confidence is rejected.
    pub fn new(confidence: f32, threshold: f32) -> Rating {
        Rating {
            confidence,
            accepted: confidence >= threshold,
        }
    }
}

/// When an estimate counts as a success for labelling training data:
/// within `theta_deg` in elevation and `phi_deg` (wrapped) in azimuth of the
/// ground truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    /// Largest elevation error of a success, degrees.
    pub theta_deg: f32,
    /// Largest wrapped azimuth error of a success, degrees.
    pub phi_deg: f32,
}

impl Default for Tolerance {
    /// Failure = |Δθ| > 10° or |Δφ| > 20°.
    fn default() -> Self {
        Tolerance {
            theta_deg: 10.0,
            phi_deg: 20.0,
        }
    }
}

impl Tolerance {
    /// Whether the estimate (θ, φ) is within tolerance of the truth; the
    /// label `d_n` of eq. 3. Non-finite angles are failures.
    pub fn reliable(&self, estimate: (f32, f32), truth: (f32, f32)) -> bool {
        let dt = (estimate.0 - truth.0).abs();
        let dp = acch_pose::phi_error(estimate.1, truth.1);
        dt <= self.theta_deg && dp <= self.phi_deg
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rating_threshold() {
        assert!(Rating::new(0.8, DEFAULT_THRESHOLD).accepted);
        assert!(!Rating::new(0.79, DEFAULT_THRESHOLD).accepted);
        assert!(!Rating::new(f32::NAN, DEFAULT_THRESHOLD).accepted);
    }

    #[test]
    fn a_detection_under_the_threshold_or_faint_with_a_weak_match_is_rejected_as_faint() {
        assert!(rejected_as_faint(1.0, 0.4));
        assert!(rejected_as_faint(1.29, 0.74));
        assert!(rejected_as_faint(1.1, f32::NAN));
        assert!(rejected_as_faint(0.99, 0.99), "under the threshold");
        assert!(
            !rejected_as_faint(1.0, 0.75),
            "at the threshold, a good match"
        );
        assert!(!rejected_as_faint(1.3, 0.4), "a clear detection");
        assert!(!rejected_as_faint(1.1, 0.75), "a good match");
        assert!(!rejected_as_faint(f32::INFINITY, 0.2), "a given mask");
        assert!(!rejected_as_faint(f32::NAN, 0.2), "no margin to judge by");
    }

    #[test]
    fn tolerance_labels() {
        let t = Tolerance::default();
        assert!(t.reliable((50.0, 355.0), (60.0, 15.0)));
        assert!(!t.reliable((50.0, 355.0), (60.5, 15.0)));
        assert!(!t.reliable((50.0, 350.0), (60.0, 15.0)));
        assert!(!t.reliable((f32::NAN, 0.0), (60.0, 0.0)));
    }
}
