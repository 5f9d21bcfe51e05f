//! Recognition: quantise the frame with the database's palette, scan the
//! cell grid for the object's window.
//!
//! Its payload ([`RecognitionPayload`]) is the frame's palette indices (one
//! byte per pixel) followed, when the object is found, by the colour counts
//! segmentation reads ([`RegionCounts`]: the cells of the search area and
//! the ring's sums), so later stages neither touch the pixels nor count
//! them again.

use super::BuildError;
use crate::config::StageSettings;
use crate::frame::FrameHeader;
use crate::stage::{ObjectWindow, Stage};
use crate::wire::{Envelope, Fault, Hop, Outcome, PixelRect, SmoothedFor, StageId};
use acch_core::{IndexImage, IndexView, Rect, ViewDatabase};
use acch_ipc::ZeroCopySend;
use acch_pose::PoseEstimator;
use acch_recognition::{
    CANDIDATES, CellRect, CountLayout, Detection, Detector, LightSearch, RecognitionModel,
    RegionCounts,
};
use acch_segmentation::Segmenter;

/// A rectangle of grid cells, `[x0, x1) x [y0, y1)`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ZeroCopySend)]
pub struct Cells {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl From<CellRect> for Cells {
    fn from(r: CellRect) -> Self {
        Cells {
            x0: r.x0,
            y0: r.y0,
            x1: r.x1,
            y1: r.y1,
        }
    }
}

impl From<Cells> for CellRect {
    fn from(c: Cells) -> Self {
        CellRect {
            x0: c.x0,
            y0: c.y0,
            x1: c.x1,
            y1: c.y1,
        }
    }
}

/// The object's window in a frame.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Window {
    /// The window in pixels, cut to the frame.
    pub window: PixelRect,
    /// The window in cells, cut to the frame.
    pub cells: Cells,
    /// Side in cells of the scan's window, before it was cut to the frame.
    pub window_cells: u32,
    /// Its vote, in [0, 1].
    pub score: f32,
    /// The model's threshold the score is measured against.
    pub threshold: f32,
    /// Scale (apparent size relative to training) the window was sized for.
    pub scale: f32,
    /// Whether the window hangs over the frame border.
    pub truncated: bool,
    /// Segmentation's search area: the payload holds its colour counts.
    pub search: Cells,
}

impl Window {
    /// How far the score cleared the threshold (score / threshold; found
    /// from [`acch_recognition::MIN_FOUND_MARGIN`]): comparable between
    /// objects whose models score on different scales.
    pub fn margin(&self) -> f32 {
        self.score / self.threshold.max(f32::MIN_POSITIVE)
    }

    /// The detection as the algorithms take it.
    pub fn detection(&self) -> Detection {
        Detection {
            window: self.window.into(),
            cells: self.cells.into(),
            score: self.score,
            threshold: self.threshold,
            scale: self.scale,
            truncated: self.truncated,
            window_cells: self.window_cells,
        }
    }
}

/// Recognition's header. `detection`: `Done` when a window was found
/// ([`acch_recognition::Detector::found_score`]), `Nothing` when none was
/// (the object is not in view).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Recognised {
    /// The frame, its trail and reads.
    pub envelope: Envelope,
    /// The object's window.
    pub detection: Outcome<Window>,
}

impl Hop for Recognised {
    fn envelope(&self) -> &Envelope {
        &self.envelope
    }
    fn envelope_mut(&mut self) -> &mut Envelope {
        &mut self.envelope
    }
}

/// Recognition's payload, read in place.
pub struct RecognitionPayload<'a> {
    /// The frame's palette indices.
    pub indices: IndexView<'a>,
    /// The colour counts of the detection's search area (`None` when the
    /// object was not found).
    pub counts: Option<RegionCounts<'a>>,
}

impl<'a> RecognitionPayload<'a> {
    /// Reads the payload of `header` from `bytes`, for a grid of `layout`.
    pub fn read(header: &Recognised, layout: CountLayout, bytes: &'a [u8]) -> Result<Self, Fault> {
        let f = &header.envelope.frame;
        let n = f.width as usize * f.height as usize;
        let (indices, rest) = bytes.split_at_checked(n).ok_or(Fault::Payload)?;
        let indices = IndexView::new(f.width, f.height, indices).ok_or(Fault::Payload)?;
        let counts = match header.detection {
            Outcome::Done(w) => {
                let search = CellRect::from(w.search);
                let len = RegionCounts::published_len(layout, search);
                let bytes = rest.get(..len).ok_or(Fault::Payload)?;
                Some(RegionCounts::from_bytes(layout, search, bytes).ok_or(Fault::Payload)?)
            }
            _ => None,
        };
        Ok(RecognitionPayload { indices, counts })
    }
}

/// The recognition stage.
pub struct Recognition {
    lights: LightSearch,
    /// Chooses a single image's light again by the pose (with the search
    /// over every light only).
    by_pose: Option<LightByPose>,
    /// The next frame's indices under the training light are already in
    /// the payload ([`Recognition::indices_written`]).
    indices_written: bool,
    detector: Detector,
    scale: Option<f32>,
    size: (u32, u32),
}

impl Recognition {
    /// The stage for `db` on frames of `settings`.
    pub fn new(db: &ViewDatabase, settings: &StageSettings) -> Result<Self, BuildError> {
        let model = recognition_model(db)?;
        let by_pose = if settings.light_search >= CANDIDATES {
            Some(LightByPose::new(db, settings)?)
        } else {
            None
        };
        Ok(Recognition {
            lights: LightSearch::new(&db.palette, settings.light_search),
            by_pose,
            indices_written: false,
            detector: Detector::new(model, settings.width, settings.height)?,
            scale: settings.scale(db),
            size: (settings.width, settings.height),
        })
    }

    /// The stage keeping the light recognition scores best, not choosing
    /// again by the pose (the evaluations compare the two; the search
    /// over every light otherwise chooses by the pose).
    pub fn choose_light_by_recognition(&mut self) {
        self.by_pose = None;
    }

    /// The stage counting a detection under a light other than the
    /// training light from `fraction` of the training score instead of
    /// [`acch_recognition::RELIT_SCORE_FRACTION`] (for measuring).
    pub fn count_relit_from(&mut self, fraction: f32) {
        self.lights.set_relit_score_fraction(fraction);
    }

    /// The stage counting a window as found from `margin` of the model's
    /// threshold instead of [`acch_recognition::MIN_FOUND_MARGIN`] (for
    /// measuring).
    pub fn find_from_margin(&mut self, margin: f32) {
        self.detector.set_min_found_margin(margin);
    }

    /// The detector (heat map and best score of the last frame).
    pub fn detector(&self) -> &Detector {
        &self.detector
    }

    /// Says that the next frame's indices under the database's palette
    /// are already in the first bytes of the payload buffer it will be
    /// handed (a [`acch_core::JointPalette`] shared by several objects
    /// wrote them): under the training light they are not quantised again.
    pub fn indices_written(&mut self) {
        self.indices_written = true;
    }

    /// Pixels of a frame: the payload's leading index bytes.
    pub fn pixels(&self) -> usize {
        self.size.0 as usize * self.size.1 as usize
    }
}

/// The light of a single image chosen by how much of the object's region
/// a training view explains ([`PoseEstimator::explained`]), over the light
/// recognition chose and its neighbours, the region grown once under the
/// light recognition chose. Recognition's own choice, the light whose
/// window scores best, favours lights that map an over exposed frame's
/// clipped inks to wrong colours (docs/accuracy.md: over exposure is lost
/// in matching).
struct LightByPose {
    model: RecognitionModel,
    segmenter: Segmenter,
    estimator: PoseEstimator,
    /// The region's mask and one light's indices over the region's box.
    mask: Vec<u8>,
    crop: IndexImage,
}

impl LightByPose {
    fn new(db: &ViewDatabase, settings: &StageSettings) -> Result<Self, BuildError> {
        Ok(LightByPose {
            model: recognition_model(db)?,
            segmenter: Segmenter::new(settings.width, settings.height)?,
            estimator: PoseEstimator::new(db.clone())?.with_roll_search(settings.roll_search_deg),
            mask: Vec::new(),
            crop: IndexImage::default(),
        })
    }

    /// `found` (on `indices`, under the light in use) under the light
    /// whose indices a view explains best; `found` itself when no region
    /// grows from it.
    fn choose(
        &mut self,
        lights: &mut LightSearch,
        detector: &mut Detector,
        (rgb, (w, h)): (&[u8], (u32, u32)),
        (indices, found): (&mut [u8], Detection),
        scale: Option<f32>,
    ) -> Option<Detection> {
        let Some(counts) = detector.region_counts(&found) else {
            return Some(found);
        };
        let view = IndexView::new(w, h, indices).expect("sized by the stage");
        let Some(segment) = self.segmenter.segment(view, &counts, &self.model, &found) else {
            return Some(found);
        };
        let roi = PixelRect::from(segment.roi.clamp_to(w, h));
        self.mask.resize(roi.area(), 0);
        super::segmentation::crop(segment.mask, w, roi, &mut self.mask);
        let (crop, mask, estimator) = (&mut self.crop, &self.mask, &mut self.estimator);
        let whole = Rect {
            x: 0,
            y: 0,
            width: roi.width,
            height: roi.height,
        };
        lights.choose_light(detector, rgb, (w, h), (indices, found), scale, |frame| {
            crop.width = roi.width;
            crop.height = roi.height;
            crop.data.resize(roi.area(), 0);
            super::segmentation::crop(frame, w, roi, &mut crop.data);
            estimator.explained(crop, mask, whole, scale)
        })
    }
}

/// The database's recognition model, or why there is none.
pub(super) fn recognition_model(db: &ViewDatabase) -> Result<RecognitionModel, BuildError> {
    RecognitionModel::from_database(db)?.ok_or_else(|| BuildError::NoRecognition {
        object: db.object.clone(),
    })
}

impl Stage for Recognition {
    const ID: StageId = StageId::Recognition;
    type Input = FrameHeader;
    type Part = Outcome<Window>;
    type Output = Recognised;

    fn max_payload(&self) -> usize {
        // Room for the counts of every cell: a search area may fill the grid.
        let layout = self.detector.count_layout();
        self.pixels() + RegionCounts::published_len(layout, layout.all_cells())
    }

    fn process(
        &mut self,
        frame: &FrameHeader,
        rgb: &[u8],
        _: &[u8],
        out: &mut [u8],
    ) -> Result<Outcome<Window>, Fault> {
        // Said for this frame only, whatever becomes of it.
        let written = std::mem::take(&mut self.indices_written);
        // A frame sent to a smoothing database for its blurred object is
        // blurred enough already (`BySet` says why it sent it).
        let blurred = frame.envelope.imaging.smoothed_for() == Some(SmoothedFor::Blur);
        self.lights.set_frame_blurred(blurred);
        let f = &frame.envelope.frame;
        if (f.width, f.height) != self.size || rgb.len() != 3 * self.pixels() {
            return Err(Fault::FrameSize);
        }
        let (w, h) = self.size;
        // Quantised straight into the output: later stages read these
        // indices where they are.
        let (index_out, counts_out) = out.split_at_mut(self.pixels());
        let found = self.lights.detect(
            &mut self.detector,
            rgb,
            (w, h),
            (index_out, written),
            self.scale,
        );
        let Some(mut d) = found else {
            return Ok(Outcome::Nothing);
        };
        if let Some(by_pose) = &mut self.by_pose {
            let Some(chosen) = by_pose.choose(
                &mut self.lights,
                &mut self.detector,
                (rgb, (w, h)),
                (index_out, d),
                self.scale,
            ) else {
                return Ok(Outcome::Nothing);
            };
            d = chosen;
        }
        let region = self.detector.region_counts(&d).ok_or(Fault::Payload)?;
        if !region.publish(counts_out) {
            return Err(Fault::Payload);
        }
        Ok(Outcome::Done(Window {
            window: d.window.into(),
            cells: d.cells.into(),
            window_cells: d.window_cells,
            score: d.score,
            threshold: d.threshold,
            scale: d.scale,
            truncated: d.truncated,
            search: region.search().into(),
        }))
    }

    fn object_window(part: &Outcome<Window>) -> Option<ObjectWindow> {
        part.done().map(|w| ObjectWindow {
            rect: w.window,
            clear: w.margin() >= 1.0,
        })
    }

    fn output(frame: &FrameHeader, detection: Outcome<Window>) -> Recognised {
        Recognised {
            envelope: frame.envelope,
            detection,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_under_the_threshold_is_found_but_not_clearly() {
        let at = |score| {
            let window = PixelRect {
                x: 8,
                y: 16,
                width: 40,
                height: 40,
            };
            Outcome::Done(Window {
                window,
                score,
                threshold: 0.3,
                ..Default::default()
            })
        };
        let found = |score| Recognition::object_window(&at(score)).map(|w| (w.rect.x, w.clear));
        assert_eq!(found(0.3), Some((8, true)));
        assert_eq!(found(0.29), Some((8, false)));
        assert_eq!(Recognition::object_window(&Outcome::Nothing), None);
    }
}
