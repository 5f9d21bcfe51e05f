//! The five processing stages as pure functions over a result message.

use super::{PipelineConfig, ResultJson, Stage};
use acch_confidence::Model as ConfidenceModel;
use acch_core::{IndexImage, IndexView, Palette, Rect, ViewDatabase};
use acch_ipc::{Fused, ResultMsg, SeedPublisher, StageId};
use acch_pose::{PoseEstimator, Refinement, Slice};
use acch_recognition::{
    CellRect, CountLayout, Detection, Detector, RecognitionModel, RegionCounts,
};
use acch_seeding::{FilterConfig, FusionError, Measurement, Outcome, ViewFilter, theta_censored};
use acch_segmentation::Segmenter;
use anyhow::{Context, Result, anyhow};
use glam::{DAffine3, DVec2};

fn scale_of(cfg: &PipelineConfig, db: &ViewDatabase) -> Option<f32> {
    cfg.distance.map(|d| db.train_distance / d as f32)
}

/// Checks that a frame or payload has the size the stage was built for;
/// a frame of another size mid-stream is skipped (and counted), never
/// processed into a wrong result.
struct SizeGuard {
    stage: &'static str,
    width: u32,
    height: u32,
    skipped: u64,
}

impl SizeGuard {
    fn new(stage: &'static str, width: u32, height: u32) -> Self {
        SizeGuard {
            stage,
            width,
            height,
            skipped: 0,
        }
    }

    fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Whether frame `msg` is `width` x `height` and `len` is
    /// `bytes_per_pixel` bytes per pixel of it.
    fn fits(&mut self, msg: &ResultMsg, len: usize, bytes_per_pixel: usize) -> bool {
        let ok = (msg.width, msg.height) == (self.width as u64, self.height as u64)
            && len == self.pixels() * bytes_per_pixel;
        if !ok {
            self.skipped += 1;
            // The first of a run is worth a line; the count goes in the
            // stage's exit summary.
            if self.skipped == 1 || self.skipped.is_power_of_two() {
                tracing::warn!(
                    "{}: frame {} is {}x{} ({len} bytes) but the pipeline runs at {}x{}: skipped ({} so far)",
                    self.stage,
                    msg.sequence,
                    msg.width,
                    msg.height,
                    self.width,
                    self.height,
                    self.skipped
                );
            }
        }
        ok
    }
}

/// Quantisation + window scan; publishes the frame's palette indices (one
/// byte per pixel) and, when the object is found, the colour counts
/// segmentation reads ([`RegionCounts`]: the cells of its search area, in
/// the header's `search_cells`, and the ring's sums), so later stages
/// neither touch the pixels nor count them again.
pub struct Recognition {
    palette: Palette,
    detector: Detector,
    scale: Option<f32>,
    size: SizeGuard,
}

impl Recognition {
    /// The stage for `cfg`, on `width` x `height` frames.
    pub fn new(cfg: &PipelineConfig, width: u32, height: u32) -> Result<Self> {
        let db = cfg.database()?;
        let model = RecognitionModel::from_database(&db)?
            .ok_or_else(|| anyhow!("the database has no recognition model"))?;
        Ok(Recognition {
            palette: db.palette.clone(),
            detector: Detector::new(model, width, height)?,
            scale: scale_of(cfg, &db),
            size: SizeGuard::new("recognition", width, height),
        })
    }
}

impl Stage for Recognition {
    const ID: StageId = StageId::Recognition;
    const NEEDS_FRAME: bool = true;
    fn payload_len(&self) -> usize {
        // Room for the counts of every cell: a search area may fill the grid.
        let layout = self.detector.count_layout();
        self.size.pixels() + RegionCounts::published_len(layout, layout.all_cells())
    }
    fn process(&mut self, msg: &mut ResultMsg, _: &[u8], frame: Option<&[u8]>, out: &mut [u8]) {
        let Some(rgb) = frame else { return };
        if !self.size.fits(msg, rgb.len(), 3) {
            return;
        }
        let (w, h) = (self.size.width, self.size.height);
        // Quantised straight into the published sample: later stages read
        // these indices where they are.
        let (index_out, counts_out) = out.split_at_mut(self.size.pixels());
        self.palette.quantise_into_slice(rgb, index_out);
        let Some(index) = IndexView::new(w, h, index_out) else {
            return;
        };
        let Some(d) = self.detector.detect(index, self.scale) else {
            return;
        };
        let Some(region) = self.detector.region_counts(&d) else {
            return;
        };
        if !region.publish(counts_out) {
            return;
        }
        msg.found = 1;
        msg.window = [d.window.x, d.window.y, d.window.width, d.window.height].map(u64::from);
        msg.cells = cells_msg(d.cells);
        msg.detection = [
            d.score as f64,
            d.threshold as f64,
            d.scale as f64,
            d.truncated as u64 as f64,
        ];
        msg.window_cells = u64::from(d.window_cells);
        msg.search_cells = cells_msg(region.search());
    }
    fn skipped(&self) -> u64 {
        self.size.skipped
    }
}

fn cells_msg(r: CellRect) -> [u64; 4] {
    [r.x0, r.y0, r.x1, r.y1].map(u64::from)
}

fn cells_of(v: [u64; 4]) -> CellRect {
    let [x0, y0, x1, y1] = v.map(|c| c.min(u64::from(u32::MAX)) as u32);
    CellRect { x0, y0, x1, y1 }
}

/// Region growing from the detection over recognition's palette indices
/// and region colour counts, read in place; publishes the mask and the
/// indices cropped to the mask's bounding box (the ROI, in the header):
/// pose's whole input, `roi.width * roi.height` bytes each, mask first.
pub struct Segmentation {
    model: RecognitionModel,
    layout: CountLayout,
    segmenter: Segmenter,
    size: SizeGuard,
}

impl Segmentation {
    /// The stage for `cfg`, on `width` x `height` frames.
    pub fn new(cfg: &PipelineConfig, width: u32, height: u32) -> Result<Self> {
        let db = cfg.database()?;
        let model = RecognitionModel::from_database(&db)?
            .ok_or_else(|| anyhow!("the database has no recognition model"))?;
        Ok(Segmentation {
            layout: CountLayout::new(&model, width, height),
            model,
            segmenter: Segmenter::new(width, height)?,
            size: SizeGuard::new("segmentation", width, height),
        })
    }
}

/// Copies `roi` of a `width`-pixel-wide one-byte-per-pixel frame into
/// `out` (`roi.area()` bytes, row-major).
fn crop(frame: &[u8], width: u32, roi: Rect, out: &mut [u8]) {
    let (w, rw) = (width as usize, roi.width as usize);
    if rw == 0 {
        return;
    }
    for (y, dst) in (roi.y as usize..).zip(out.chunks_exact_mut(rw)) {
        let at = y * w + roi.x as usize;
        dst.copy_from_slice(&frame[at..at + rw]);
    }
}

fn rect(v: [u64; 4]) -> Rect {
    Rect {
        x: v[0] as u32,
        y: v[1] as u32,
        width: v[2] as u32,
        height: v[3] as u32,
    }
}

impl Stage for Segmentation {
    const ID: StageId = StageId::Segmentation;
    const NEEDS_FRAME: bool = false;
    fn payload_len(&self) -> usize {
        2 * self.size.pixels()
    }
    fn process(&mut self, msg: &mut ResultMsg, input: &[u8], _: Option<&[u8]>, out: &mut [u8]) {
        let n = self.size.pixels();
        if msg.found != 1 || !self.size.fits(msg, input.len().min(n), 1) {
            return;
        }
        let (index, rest) = input.split_at(n);
        let Some(index) = IndexView::new(self.size.width, self.size.height, index) else {
            return;
        };
        let search = cells_of(msg.search_cells);
        let Some(counts) = rest
            .get(..RegionCounts::published_len(self.layout, search))
            .and_then(|bytes| RegionCounts::from_bytes(self.layout, search, bytes))
        else {
            return;
        };
        let det = Detection {
            window: rect(msg.window),
            cells: cells_of(msg.cells),
            score: msg.detection[0] as f32,
            threshold: msg.detection[1] as f32,
            scale: msg.detection[2] as f32,
            truncated: msg.detection[3] != 0.0,
            window_cells: msg.window_cells.min(u64::from(u32::MAX)) as u32,
        };
        if let Some(seg) = self.segmenter.segment(index, &counts, &self.model, &det)
            && seg.mask.len() == n
        {
            let roi = seg.roi.clamp_to(self.size.width, self.size.height);
            let area = roi.area() as usize;
            let (mask_out, index_out) = out[..2 * area].split_at_mut(area);
            crop(seg.mask, self.size.width, roi, mask_out);
            crop(index.data, self.size.width, roi, index_out);
            msg.segmented = 1;
            msg.roi = [roi.x, roi.y, roi.width, roi.height].map(u64::from);
        }
    }
    fn skipped(&self) -> u64 {
        self.size.skipped
    }
}

/// ACCH of the segmented ROI (segmentation's crop) and the match-value
/// response (published as the payload, f32 native-endian).
pub struct Pose {
    estimator: PoseEstimator,
    index: IndexImage,
    scale: Option<f32>,
    views: usize,
    size: SizeGuard,
}

impl Pose {
    /// The stage for `cfg`, on `width` x `height` frames.
    pub fn new(cfg: &PipelineConfig, width: u32, height: u32) -> Result<Self> {
        let db = cfg.database()?;
        Ok(Pose {
            scale: scale_of(cfg, &db),
            views: db.views().len(),
            estimator: PoseEstimator::new(db)?,
            index: IndexImage::new(width, height, vec![0; width as usize * height as usize]),
            size: SizeGuard::new("pose", width, height),
        })
    }
}

impl Stage for Pose {
    const ID: StageId = StageId::Pose;
    const NEEDS_FRAME: bool = false;
    fn payload_len(&self) -> usize {
        self.views * 4
    }
    fn process(&mut self, msg: &mut ResultMsg, input: &[u8], _: Option<&[u8]>, out: &mut [u8]) {
        if msg.segmented != 1 || !self.size.fits(msg, input.len(), 2) {
            return;
        }
        let roi = rect(msg.roi);
        let area = roi.area() as usize;
        if roi.clamp_to(self.size.width, self.size.height) != roi || area == 0 {
            return;
        }
        let (mask, index) = input[..2 * area].split_at(area);
        // The crop is small: one copy into a buffer sized for a whole frame
        // (no allocation), as the estimator takes an owned image.
        self.index.width = roi.width;
        self.index.height = roi.height;
        self.index.data.clear();
        self.index.data.extend_from_slice(index);
        let crop = Rect { x: 0, y: 0, ..roi };
        let Some(e) = self.estimator.estimate(
            &self.index,
            Some(mask),
            crop,
            self.scale,
            Refinement::Parabolic,
        ) else {
            return;
        };
        msg.estimated = 1;
        msg.estimate = [
            e.theta_deg as f64,
            e.phi_deg as f64,
            e.best_value as f64,
            e.scale as f64,
        ];
        msg.best_view = e.best_view as u64;
        msg.accepted = 1;
        msg.confidence = 1.0;
        for (dst, v) in out.chunks_exact_mut(4).zip(self.estimator.response()) {
            dst.copy_from_slice(&v.to_ne_bytes());
        }
    }
    fn skipped(&self) -> u64 {
        self.size.skipped
    }
}

/// The confidence network over the response.
pub struct Confidence {
    model: Option<ConfidenceModel>,
    slices: Vec<Slice>,
    views: Vec<acch_core::View>,
    response: Vec<f32>,
}

impl Confidence {
    /// The stage for `cfg`.
    pub fn new(cfg: &PipelineConfig) -> Result<Self> {
        let db = cfg.database()?;
        let model = match ConfidenceModel::load(&db) {
            Ok(m) => Some(m),
            Err(acch_confidence::ConfidenceError::MissingSection) => None,
            Err(e) => return Err(e).context("reading the confidence network"),
        };
        Ok(Confidence {
            model,
            slices: acch_pose::slices(&db),
            response: Vec::with_capacity(db.views().len()),
            views: db.views().to_vec(),
        })
    }
}

impl Stage for Confidence {
    const ID: StageId = StageId::Confidence;
    const NEEDS_FRAME: bool = false;
    fn payload_len(&self) -> usize {
        0
    }
    fn process(&mut self, msg: &mut ResultMsg, response: &[u8], _: Option<&[u8]>, _: &mut [u8]) {
        if msg.estimated == 0 {
            return;
        }
        let Some(model) = &self.model else { return };
        self.response.clear();
        self.response.extend(
            response
                .chunks_exact(4)
                .map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])),
        );
        if self.response.len() != self.views.len() {
            return;
        }
        let r = model.rating(&self.response, &self.slices, &self.views);
        msg.rated = 1;
        msg.confidence = r.confidence as f64;
        msg.accepted = r.accepted as u64;
    }
}

/// SE(3) seeds; publishes seed and result on zenoh.
pub struct Seeding {
    object: String,
    grid: acch_seeding::GridSpacing,
    train_distance: f64,
    distance: Option<f64>,
    zenoh: SeedPublisher,
    covariance: acch_seeding::CovarianceModel,
    filter: ViewFilter,
    /// The database's lowest θ slice: an estimate there may stand for any
    /// view below it, so it fuses φ only.
    lowest_theta_deg: f64,
    /// The arm's camera pose at the last frame, to predict by the motion
    /// since (absolute poses, so frames dropped upstream cost nothing).
    last_arm: Option<DAffine3>,
}

impl Seeding {
    /// The stage for `cfg` (opens the zenoh session).
    pub fn new(cfg: &PipelineConfig) -> Result<Self> {
        let db = cfg.database()?;
        let grid = acch_seeding::grid_spacing(
            db.views()
                .iter()
                .map(|v| (v.theta_deg as f64, v.phi_deg as f64)),
        );
        Ok(Seeding {
            object: db.object.clone(),
            grid,
            train_distance: db.train_distance as f64,
            distance: cfg.distance,
            zenoh: SeedPublisher::new(&cfg.zenoh, &cfg.object)?,
            covariance: Default::default(),
            filter: ViewFilter::new(FilterConfig::default())?,
            lowest_theta_deg: db
                .views()
                .iter()
                .map(|v| v.theta_deg as f64)
                .fold(f64::INFINITY, f64::min),
            last_arm: None,
        })
    }
}

impl Stage for Seeding {
    const ID: StageId = StageId::Seeding;
    const NEEDS_FRAME: bool = false;
    fn payload_len(&self) -> usize {
        0
    }
    fn process(&mut self, msg: &mut ResultMsg, _: &[u8], _: Option<&[u8]>, _: &mut [u8]) {
        self.predict(msg);
        let outcome = self.seed(msg);
        self.publish_fused(msg, outcome);
    }
    fn sink(&mut self, msg: &ResultMsg) -> Result<()> {
        let r = ResultJson::of(&self.object, msg);
        if let Some(seed) = &r.seed {
            self.zenoh.put_seed(serde_json::to_vec(seed)?)?;
        }
        self.zenoh.put_result(serde_json::to_vec(&r)?)?;
        Ok(())
    }
}

impl Seeding {
    /// Carries the fused pose through the arm's motion since the last
    /// frame; without the arm's pose the motion is unknown and the fused
    /// pose is dropped.
    fn predict(&mut self, msg: &ResultMsg) {
        if msg.arm.valid != 1 {
            self.filter.reset();
            self.last_arm = None;
            return;
        }
        let arm = DAffine3::from_cols_array(&msg.arm.world_from_camera);
        if let Some(last) = self.last_arm
            && let Err(e) = self.filter.predict(&(last.inverse() * arm))
        {
            tracing::warn!("frame {}: {e}: fused pose dropped", msg.sequence);
            self.filter.reset();
        }
        self.last_arm = Some(arm);
    }

    /// Seeds an accepted estimate and fuses it; returns what the filter did
    /// with it (0 when there was nothing to fuse, as in [`acch_ipc::Fused`]).
    fn seed(&mut self, msg: &mut ResultMsg) -> u64 {
        if msg.estimated == 0 || msg.accepted == 0 {
            msg.accepted = 0;
            return 0;
        }
        let roi = msg.roi;
        let input = acch_seeding::SeedInput {
            theta_deg: msg.estimate[0].clamp(0.0, 90.0),
            phi_deg: msg.estimate[1],
            roi_centre_px: DVec2::new(
                roi[0] as f64 + (roi[2] as f64 - 1.0) / 2.0,
                roi[1] as f64 + (roi[3] as f64 - 1.0) / 2.0,
            ),
            intrinsics: acch_seeding::Pinhole {
                fx: msg.intrinsics[0],
                fy: msg.intrinsics[1],
                cx: msg.intrinsics[2],
                cy: msg.intrinsics[3],
            },
            distance: match self.distance {
                Some(d) => acch_seeding::Distance::Known {
                    value: d,
                    sigma: 0.02 * d,
                },
                None => acch_seeding::Distance::FromScale {
                    train_distance: self.train_distance,
                    scale: msg.estimate[3].max(1e-3),
                    relative_sigma: 0.1,
                },
            },
            confidence: msg.confidence.clamp(0.0, 1.0),
            grid: self.grid,
        };
        match acch_seeding::seed(&input, &self.covariance) {
            Ok(s) => {
                msg.seeded = 1;
                msg.seed_translation = s.translation().to_array();
                msg.seed_rotation_xyzw = s.rotation().to_array();
                msg.seed_covariance = s.covariance;
            }
            Err(e) => {
                tracing::warn!("frame {}: no seed: {e}", msg.sequence);
                msg.accepted = 0;
                return 0;
            }
        }
        if self.last_arm.is_none() {
            return 0;
        }
        let censored = theta_censored(input.theta_deg, self.lowest_theta_deg);
        let fused = Measurement::from_estimate(&input, &self.covariance)
            .map(|m| if censored { m.without_theta(&input) } else { m })
            .map_err(|e| FusionError::InvalidMeasurement(e.to_string()))
            .and_then(|m| self.filter.update(&m));
        match fused {
            Ok(Outcome::Initialised) => 1,
            Ok(Outcome::Fused { .. }) => 2,
            Ok(Outcome::Gated { .. }) => 3,
            Ok(Outcome::Reinitialised { .. }) => 4,
            Err(e) => {
                tracing::warn!("frame {}: not fused: {e}", msg.sequence);
                0
            }
        }
    }

    fn publish_fused(&self, msg: &mut ResultMsg, outcome: u64) {
        msg.fused = match self.filter.state() {
            Some(f) => Fused {
                valid: 1,
                outcome,
                view_deg: [f.theta_deg, f.phi_deg],
                view_covariance_deg2: [
                    f.view_covariance_deg2[0][0],
                    f.view_covariance_deg2[0][1],
                    f.view_covariance_deg2[1][0],
                    f.view_covariance_deg2[1][1],
                ],
                camera_from_object: f.camera_from_object,
                rotation_covariance: std::array::from_fn(|i| f.rotation_covariance[i / 3][i % 3]),
                fused: f.fused as u64,
                since_update: f.since_update as u64,
            },
            None => Fused::default(),
        };
    }
}

#[cfg(test)]
mod tests {
    use super::super::{FRAME_READERS, Stage};
    use super::*;

    #[test]
    fn a_cropped_mask_pastes_back_into_the_frame() {
        let (w, h) = (13u32, 9u32);
        let roi = Rect {
            x: 3,
            y: 2,
            width: 6,
            height: 5,
        };
        let mut mask = vec![0u8; (w * h) as usize];
        for y in roi.y..roi.y + roi.height {
            for x in roi.x..roi.x + roi.width {
                mask[(y * w + x) as usize] = if (x + y) % 3 == 0 { 0 } else { 255 };
            }
        }
        let mut payload = vec![7u8; 2 * (w * h) as usize];
        crop(&mask, w, roi, &mut payload[..roi.area() as usize]);
        let msg = ResultMsg {
            width: w as u64,
            height: h as u64,
            roi: [roi.x, roi.y, roi.width, roi.height].map(u64::from),
            ..Default::default()
        };
        let mut back = Vec::new();
        assert!(crate::cmd::observe::frame_mask(&msg, &payload, &mut back));
        assert_eq!(back, mask);
        // An ROI outside the frame is refused, not read out of bounds.
        let outside = ResultMsg {
            roi: [10, 2, 6, 5],
            ..msg
        };
        assert!(!crate::cmd::observe::frame_mask(
            &outside, &payload, &mut back
        ));
        assert!(back.is_empty());
    }

    #[test]
    fn frame_readers_are_the_stages_that_need_frames() {
        let needs = [
            (StageId::Recognition, Recognition::NEEDS_FRAME),
            (StageId::Segmentation, Segmentation::NEEDS_FRAME),
            (StageId::Pose, Pose::NEEDS_FRAME),
            (StageId::Confidence, Confidence::NEEDS_FRAME),
            (StageId::Seeding, Seeding::NEEDS_FRAME),
        ];
        for (id, needs_frame) in needs {
            assert_eq!(FRAME_READERS.contains(&id), needs_frame, "{id:?}");
        }
    }
}
