//! The five processing stages, each written once with its typed header and
//! payload view beside it. Data flows one way: recognition -> segmentation
//! -> pose -> confidence -> seeding; every header carries the one before
//! it, so the final [`Seeded`] holds every stage's part of a frame.

pub mod by_set;
pub mod confidence;
pub mod pose;
pub mod recognition;
pub mod seeding;
pub mod segmentation;

pub use by_set::{BySet, Chosen};
pub use confidence::{Confidence, Evidence, Rated, Rating, Rules, Verdict};
pub use pose::{
    COLOUR_ANCHORED_FROM, Pose, PoseEstimate, Posed, ResponsePayload, ShapeFit, colour_trust,
    fit_covariance_matrix, fit_pose, fit_view, pose_helper, share_with_helper,
};
pub use recognition::{Cells, Recognised, Recognition, RecognitionPayload, Window};
pub use seeding::{FusedPose, Fusion, SeedPose, Seeded, Seeding, SeedingPart};
pub use segmentation::{RegionPayload, Segmentation, Segmented};

use crate::config::StageSettings;
use acch_core::ViewDatabase;

/// Lights recognition tries in a weak single image when the light search
/// is on (`acch eval --light-search`, the robust protocol): all of them
/// ([`StageSettings::light_search`]), the light then chosen again by the
/// pose (docs/accuracy.md, "The light chosen by the pose"). It is off by
/// default: on an object
/// of flat, exact colours it turns "not found" into wrong estimates the
/// confidence network accepts (docs/accuracy.md).
pub const SINGLE_IMAGE_LIGHT_SEARCH: usize = acch_recognition::CANDIDATES;

/// Why a stage could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The database has no recognition model.
    #[error("the database of '{object}' has no recognition model: retrain it with `acch train`")]
    NoRecognition {
        /// The database's object.
        object: String,
    },
    /// The database has neither a confidence network nor its object's
    /// shape, and the run is not unrated.
    #[error(
        "the database of '{object}' has no confidence network and no shape of its object, so no \
         estimate could be rated: retrain it with `acch train` from the object or its mesh \
         (--confidence-scenes > 0), or run it unrated (--unrated: estimates are reported, none \
         is accepted, no seed is published)"
    )]
    NoConfidence {
        /// The database's object.
        object: String,
    },
    /// The recognition model is unusable.
    #[error(transparent)]
    Recognition(#[from] acch_recognition::RecognitionError),
    /// The threads of several objects' lanes could not be started.
    #[error("could not start the threads of the objects' lanes: {0}")]
    Threads(String),
    /// The segmenter refused the frame size.
    #[error(transparent)]
    Segmentation(#[from] acch_segmentation::SegmentationError),
    /// The database cannot estimate poses.
    #[error(transparent)]
    Pose(#[from] acch_pose::PoseError),
    /// The confidence network is unusable.
    #[error(transparent)]
    Confidence(#[from] acch_confidence::ConfidenceError),
    /// The database's shape is damaged.
    #[error("the database's shape is unreadable")]
    Shape(#[source] acch_shape::StoredShapeError),
    /// The fusion filter's configuration is invalid.
    #[error(transparent)]
    Fusion(#[from] acch_seeding::FusionError),
    /// The smoothed set's database cannot stand in for the sharp one on a
    /// noisy frame.
    #[error(
        "the smoothed database of '{object}' {why}: train it with `acch train --smoothing \
         binomial --confidence-imaging` from the sharp database's object and views"
    )]
    SmoothedSet {
        /// The sharp database's object.
        object: String,
        /// What does not fit.
        why: String,
    },
}

/// The five stages of one pipeline, built from one database or, in a run
/// that chooses per frame, from a sharp and a smoothed one ([`BySet`]).
pub struct Stages {
    /// Quantise + window scan; measures and chooses the set.
    pub recognition: BySet<Recognition>,
    /// Region growing.
    pub segmentation: BySet<Segmentation>,
    /// ACCH pose.
    pub pose: BySet<Pose>,
    /// Confidence network.
    pub confidence: BySet<Confidence>,
    /// Seed and fusion, one for both sets: its fusion spans their frames.
    pub seeding: Seeding,
}

impl Stages {
    /// Every stage for `db` with `settings`.
    pub fn new(db: &ViewDatabase, settings: &StageSettings) -> Result<Self, BuildError> {
        Self::for_sets(db, None, settings)
    }

    /// Every stage for the sharp database `sharp` and, when given, the
    /// smoothed one `smoothed`, chosen per frame, with `settings`.
    pub fn for_sets(
        sharp: &ViewDatabase,
        smoothed: Option<&ViewDatabase>,
        settings: &StageSettings,
    ) -> Result<Self, BuildError> {
        Ok(Stages {
            recognition: by_set((sharp, smoothed, settings), Recognition::new)?,
            segmentation: by_set((sharp, smoothed, settings), Segmentation::new)?,
            pose: by_set((sharp, smoothed, settings), Pose::new)?,
            confidence: by_set((sharp, smoothed, settings), Confidence::new)?,
            seeding: Seeding::new(sharp, settings)?,
        })
    }
}

/// Stage `S` built by `new` for the sharp database and, when given, the
/// smoothed one (checked to stand in for it), with the settings.
pub fn by_set<S: crate::Stage>(
    (sharp, smoothed, settings): (&ViewDatabase, Option<&ViewDatabase>, &StageSettings),
    new: fn(&ViewDatabase, &StageSettings) -> Result<S, BuildError>,
) -> Result<BySet<S>, BuildError> {
    let Some(smoothed) = smoothed else {
        return Ok(BySet::sharp_only(new(sharp, settings)?));
    };
    check_smoothed(sharp, smoothed)?;
    Ok(BySet::both(new(sharp, settings)?, new(smoothed, settings)?))
}

/// Whether `smoothed` can stand in for `sharp` on a noisy frame: the same
/// object seen from the same views at the same distance, its palette
/// smoothing frames.
fn check_smoothed(sharp: &ViewDatabase, smoothed: &ViewDatabase) -> Result<(), BuildError> {
    let views = |db: &ViewDatabase| -> Vec<(f32, f32)> {
        db.views()
            .iter()
            .map(|v| (v.theta_deg, v.phi_deg))
            .collect()
    };
    let why = if smoothed.object != sharp.object {
        Some(format!("is of another object ('{}')", smoothed.object))
    } else if smoothed.palette.smoothing() == acch_core::Smoothing::Off {
        Some("does not smooth frames".to_owned())
    } else if smoothed.train_distance_m != sharp.train_distance_m || views(smoothed) != views(sharp)
    {
        Some("was trained from other views or another distance".to_owned())
    } else {
        None
    };
    match why {
        Some(why) => Err(BuildError::SmoothedSet {
            object: sharp.object.clone(),
            why,
        }),
        None => Ok(()),
    }
}
