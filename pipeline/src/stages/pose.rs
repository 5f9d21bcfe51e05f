//! Pose: the ACCH of the segmented region, matched against every view of
//! the database; the estimate is the best view, refined between grid
//! points.
//!
//! Its payload ([`ResponsePayload`]) is the match-value response, one f32
//! (native-endian) per database view in database order.

use super::segmentation::{RegionPayload, Segmented};
use super::{BuildError, StageSettings};
use crate::stage::Stage;
use crate::wire::{Envelope, Fault, Hop, Outcome, StageId};
use acch_core::{IndexImage, Rect, ViewDatabase};
use acch_ipc::ZeroCopySend;
use acch_pose::{PoseEstimator, Refinement};

/// A 2-DOF pose estimate.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct PoseEstimate {
    /// Elevation θ, degrees.
    pub theta_deg: f32,
    /// Azimuth φ, degrees in [0, 360).
    pub phi_deg: f32,
    /// The best view's match value (histogram intersection), in [0, 1].
    pub best_value: f32,
    /// Apparent size relative to training the histogram was taken at.
    pub scale: f32,
    /// Index of the best view in the database.
    pub best_view: u32,
    /// The camera's roll about its optical axis, degrees (0 when the roll
    /// is not searched).
    pub roll_deg: f32,
    /// How much more of the region's coloured area a view 20-60° away in
    /// azimuth holds in place than the best view
    /// ([`PoseEstimator::map_rival`]); `-inf` when nothing was
    /// weighed (a database without colour maps), NaN when the region could
    /// not be placed.
    pub map_rival: f32,
}

/// Pose's header. `pose`: `Nothing` when the region held no pair of object
/// colours.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Posed {
    /// Segmentation's header.
    pub segmented: Segmented,
    /// The estimate.
    pub pose: Outcome<PoseEstimate>,
}

impl Hop for Posed {
    fn envelope(&self) -> &Envelope {
        self.segmented.envelope()
    }
    fn envelope_mut(&mut self) -> &mut Envelope {
        self.segmented.envelope_mut()
    }
}

/// Pose's payload, read in place.
#[derive(Clone, Copy, Debug)]
pub struct ResponsePayload<'a> {
    bytes: &'a [u8],
}

impl<'a> ResponsePayload<'a> {
    /// Reads the response of `header` over a database of `views` views;
    /// `Ok(None)` when nothing was estimated.
    pub fn read(header: &Posed, views: usize, bytes: &'a [u8]) -> Result<Option<Self>, Fault> {
        if header.pose.done().is_none() {
            return Ok(None);
        }
        let bytes = bytes.get(..4 * views).ok_or(Fault::Response)?;
        Ok(Some(ResponsePayload { bytes }))
    }

    /// Views in the response.
    pub fn len(&self) -> usize {
        self.bytes.len() / 4
    }

    /// Whether it holds no view.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// The match values, in view order.
    pub fn values(&self) -> impl Iterator<Item = f32> + 'a {
        self.bytes
            .chunks_exact(4)
            .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
    }

    /// The match values into `out` (cleared first; no allocation once it
    /// has room).
    pub fn copy_into(&self, out: &mut Vec<f32>) {
        out.clear();
        out.extend(self.values());
    }
}

/// Writes `response` as pose's payload into `out`.
fn write_response(response: &[f32], out: &mut [u8]) -> Result<(), Fault> {
    let out = out.get_mut(..4 * response.len()).ok_or(Fault::Payload)?;
    for (dst, v) in out.chunks_exact_mut(4).zip(response) {
        dst.copy_from_slice(&v.to_ne_bytes());
    }
    Ok(())
}

/// The pose stage.
pub struct Pose {
    estimator: PoseEstimator,
    /// The ROI's palette indices (the estimator takes an owned image): a
    /// buffer sized for a whole frame, so copying a crop in never allocates.
    index: IndexImage,
    scale: Option<f32>,
    refinement: Refinement,
}

impl Pose {
    /// The stage for `db` on frames of `settings`.
    pub fn new(db: &ViewDatabase, settings: &StageSettings) -> Result<Self, BuildError> {
        let (w, h) = (settings.width, settings.height);
        let estimator = PoseEstimator::new(db.clone())?.with_roll_search(settings.roll_search_deg);
        if !estimator.has_view_maps() {
            tracing::warn!(
                "the database of '{}' records no colour maps of its views (trained before \
                 them): no estimate is weighed against where its region lies; train it again \
                 for that check",
                db.object
            );
        }
        Ok(Pose {
            scale: settings.scale(db),
            estimator,
            index: IndexImage::new(w, h, vec![0; w as usize * h as usize]),
            refinement: Refinement::Parabolic,
        })
    }

    /// The stage refining the best view by `refinement` instead (the
    /// evaluations compare winner takes all).
    pub fn with_refinement(mut self, refinement: Refinement) -> Self {
        self.refinement = refinement;
        self
    }

    /// The estimator (the database and the response of the last frame).
    pub fn estimator(&self) -> &PoseEstimator {
        &self.estimator
    }
}

impl Stage for Pose {
    const ID: StageId = StageId::Pose;
    type Input = Segmented;
    type Part = Outcome<PoseEstimate>;
    type Output = Posed;

    fn max_payload(&self) -> usize {
        4 * self.estimator.database().views().len()
    }

    fn process(
        &mut self,
        input: &Segmented,
        payload: &[u8],
        out: &mut [u8],
    ) -> Result<Outcome<PoseEstimate>, Fault> {
        let Some(region) = RegionPayload::read(input, payload)? else {
            return Ok(Outcome::Skipped);
        };
        let roi = region.roi;
        self.index.width = roi.width;
        self.index.height = roi.height;
        self.index.data.clear();
        self.index.data.extend_from_slice(region.indices);
        let crop = Rect {
            x: 0,
            y: 0,
            width: roi.width,
            height: roi.height,
        };
        let Some(e) = self.estimator.estimate(
            &self.index,
            Some(region.mask),
            crop,
            self.scale,
            self.refinement,
        ) else {
            return Ok(Outcome::Nothing);
        };
        write_response(self.estimator.response(), out)?;
        let map_rival = self.estimator.map_rival(
            &self.index,
            Some(region.mask),
            crop,
            &e,
            acch_confidence::DEFAULT_MIN_PHI_SEPARATION_DEG,
        );
        Ok(Outcome::Done(PoseEstimate {
            theta_deg: e.theta_deg,
            phi_deg: e.phi_deg,
            best_value: e.best_value,
            scale: e.scale,
            best_view: e.best_view as u32,
            roll_deg: e.roll_deg,
            map_rival,
        }))
    }

    fn output(input: &Segmented, pose: Outcome<PoseEstimate>) -> Posed {
        Posed {
            segmented: *input,
            pose,
        }
    }
}
