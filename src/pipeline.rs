//! The stage functions chained in one process: quantise + recognise,
//! segment, estimate the pose, rate the confidence. `acch run`, `acch
//! estimate` without a mask and the evaluations all go through this one
//! chain, so they measure the same thing.

use acch_confidence::{Model as ConfidenceModel, Rating};
use acch_core::{IndexImage, Rect, ViewDatabase};
use acch_pose::{Estimate, PoseEstimator, Refinement};
use acch_recognition::{Detection, Detector, RecognitionModel};
use acch_segmentation::Segmenter;
use anyhow::{Context, Result, anyhow};
use std::time::Instant;

/// Wall-clock time each stage took on one frame, nanoseconds.
#[derive(Clone, Copy, Debug, Default)]
pub struct StageTimes {
    /// Quantisation and window scan.
    pub recognition_ns: u64,
    /// Region growing to a pixel mask.
    pub segmentation_ns: u64,
    /// Histogram, response and refinement.
    pub pose_ns: u64,
    /// Confidence network.
    pub confidence_ns: u64,
}

impl StageTimes {
    /// Sum over the stages.
    pub fn total_ns(&self) -> u64 {
        self.recognition_ns + self.segmentation_ns + self.pose_ns + self.confidence_ns
    }
}

/// What the chain made of one frame.
#[derive(Clone, Copy, Debug)]
pub struct FrameResult {
    /// The detection window, when the object was found.
    pub detection: Option<Detection>,
    /// Bounding box of the segmented mask.
    pub roi: Option<Rect>,
    /// The pose, when the object was found and segmented.
    pub estimate: Option<Estimate>,
    /// The confidence rating, when the database carries a network.
    pub rating: Option<Rating>,
    /// Per-stage times.
    pub times: StageTimes,
}

impl FrameResult {
    /// Whether a pose is reported: estimated and, when rated, accepted.
    pub fn accepted(&self) -> bool {
        self.estimate.is_some() && self.rating.is_none_or(|r| r.accepted)
    }
}

/// Recognition, segmentation, pose and confidence over one database.
pub struct Pipeline {
    estimator: PoseEstimator,
    detector: Detector,
    segmenter: Segmenter,
    confidence: Option<ConfidenceModel>,
    index: IndexImage,
    /// Known apparent scale (from a known distance), else from the ROI.
    scale: Option<f32>,
    refinement: Refinement,
}

impl Pipeline {
    /// A chain for `width` x `height` frames. The database must carry a
    /// recognition model; the confidence network is optional.
    pub fn new(db: ViewDatabase, width: u32, height: u32, distance: Option<f32>) -> Result<Self> {
        let recognition = RecognitionModel::from_database(&db)?.ok_or_else(|| {
            anyhow!(
                "the database of '{}' has no recognition model: retrain it with `acch train`",
                db.object
            )
        })?;
        let confidence = match ConfidenceModel::load(&db) {
            Ok(m) => Some(m),
            Err(acch_confidence::ConfidenceError::MissingSection) => None,
            Err(e) => return Err(e).context("reading the confidence network"),
        };
        let scale = distance.map(|d| db.train_distance / d);
        Ok(Pipeline {
            detector: Detector::new(recognition, width, height)?,
            segmenter: Segmenter::new(width, height)?,
            estimator: PoseEstimator::new(db)?,
            confidence,
            index: IndexImage::default(),
            scale,
            refinement: Refinement::Parabolic,
        })
    }

    /// Drops the confidence network (to collect its training data).
    pub fn without_confidence(mut self) -> Self {
        self.confidence = None;
        self
    }

    /// The pose estimator (database, response of the last frame).
    pub fn estimator(&self) -> &PoseEstimator {
        &self.estimator
    }

    /// The detector (heat map of the last frame).
    pub fn detector(&self) -> &Detector {
        &self.detector
    }

    /// The segmenter (cell scores and mask of the last frame).
    pub fn segmenter(&self) -> &Segmenter {
        &self.segmenter
    }

    /// The confidence network, if any.
    pub fn confidence(&self) -> Option<&ConfidenceModel> {
        self.confidence.as_ref()
    }

    /// The last frame's palette indices.
    pub fn index_image(&self) -> &IndexImage {
        &self.index
    }

    /// Runs every stage on a packed RGB frame.
    pub fn process(&mut self, rgb: &[u8], width: u32, height: u32) -> FrameResult {
        let mut times = StageTimes::default();
        let t = Instant::now();
        self.estimator
            .database()
            .palette
            .quantise_into(rgb, width, height, &mut self.index);
        let detection = self.detector.detect(&self.index, self.scale);
        times.recognition_ns = t.elapsed().as_nanos() as u64;
        let mut result = FrameResult {
            detection,
            roi: None,
            estimate: None,
            rating: None,
            times,
        };
        let Some(det) = detection else {
            return result;
        };
        let t = Instant::now();
        let segment = self
            .segmenter
            .segment_detected(&self.index, &self.detector, &det);
        result.times.segmentation_ns = t.elapsed().as_nanos() as u64;
        let Some(segment) = segment else {
            return result;
        };
        result.roi = Some(segment.roi);
        let t = Instant::now();
        result.estimate = self.estimator.estimate(
            &self.index,
            Some(segment.mask),
            segment.roi,
            self.scale,
            self.refinement,
        );
        result.times.pose_ns = t.elapsed().as_nanos() as u64;
        if result.estimate.is_some()
            && let Some(model) = &self.confidence
        {
            let t = Instant::now();
            result.rating = Some(model.rating(
                self.estimator.response(),
                self.estimator.slices(),
                self.estimator.database().views(),
            ));
            result.times.confidence_ns = t.elapsed().as_nanos() as u64;
        }
        result
    }
}
