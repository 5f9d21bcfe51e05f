//! What every hop's header carries, whichever stage wrote it: the frame's
//! description, its timing trail and how its pixels were read (the
//! [`Envelope`]), plus the building blocks of the stages' own parts
//! ([`Outcome`], [`Maybe`], [`Fault`]).
//!
//! Every type here is `#[repr(C)]` plain data that lives in shared memory as
//! it is (iceoryx2 `ZeroCopySend`). A header is written whole by the one
//! process that publishes it, so a reader only ever sees values the writer
//! built; the processes of a run are the same binary.

use acch_capture::calibration::{Calibration, Distortion, DistortionModel};
use acch_ipc::ZeroCopySend;

/// The processes of the pipeline, in data-flow order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(usize)]
pub enum StageId {
    /// Frame source.
    Capture = 0,
    /// Quantise + window scan.
    Recognition = 1,
    /// Region growing.
    Segmentation = 2,
    /// ACCH pose.
    Pose = 3,
    /// Confidence network.
    Confidence = 4,
    /// SE(3) seed and fusion.
    Seeding = 5,
}

/// Number of stages, capture included.
pub const STAGES: usize = 6;

impl StageId {
    /// Every stage in data-flow order.
    pub const ALL: [StageId; STAGES] = [
        StageId::Capture,
        StageId::Recognition,
        StageId::Segmentation,
        StageId::Pose,
        StageId::Confidence,
        StageId::Seeding,
    ];

    /// The stage's name on the command line, in reports and as its stream.
    pub fn name(self) -> &'static str {
        match self {
            StageId::Capture => "capture",
            StageId::Recognition => "recognition",
            StageId::Segmentation => "segmentation",
            StageId::Pose => "pose",
            StageId::Confidence => "confidence",
            StageId::Seeding => "seeding",
        }
    }

    /// Parses a stage name.
    pub fn from_name(name: &str) -> Option<StageId> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// The stage before this one (`None` for capture).
    pub fn upstream(self) -> Option<StageId> {
        (self as usize).checked_sub(1).map(|i| Self::ALL[i])
    }
}

/// A value that may be absent: `Option` with a defined layout.
#[repr(C, u32)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Maybe<T> {
    /// Not known.
    #[default]
    Absent,
    /// Known.
    Present(T),
}

// SAFETY: repr(C, u32) over a ZeroCopySend payload: no pointers, a fixed
// layout, the same in every process of the binary.
unsafe impl<T: ZeroCopySend> ZeroCopySend for Maybe<T> {}

impl<T: Copy> Maybe<T> {
    /// As an `Option`.
    pub fn get(&self) -> Option<T> {
        match self {
            Maybe::Absent => None,
            Maybe::Present(v) => Some(*v),
        }
    }
}

impl<T> From<Option<T>> for Maybe<T> {
    fn from(v: Option<T>) -> Self {
        match v {
            None => Maybe::Absent,
            Some(v) => Maybe::Present(v),
        }
    }
}

/// Why a stage could not process a frame it was given. The frame still
/// goes on (marked [`Outcome::Failed`]) and the fault is counted in the
/// stage's counters: nothing is dropped silently.
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, thiserror::Error)]
pub enum Fault {
    /// The frame is not the size the stage was built for.
    #[error("the frame is not the pipeline's size")]
    FrameSize = 1,
    /// The payload is shorter than, or inconsistent with, what its header
    /// describes.
    #[error("the payload does not match its header")]
    Payload = 2,
    /// A header value is out of range (a region outside the frame).
    #[error("a header value is out of range")]
    Header = 3,
    /// The match-value response does not have one value per database view,
    /// or holds values the confidence network cannot rate.
    #[error("the response cannot be rated")]
    Response = 4,
    /// The seed could not be built from the estimate (degenerate
    /// intrinsics, distance or region).
    #[error("no seed can be built from the estimate")]
    Seed = 5,
}

// SAFETY: a fieldless repr(u32) enum: four bytes, no pointers.
unsafe impl ZeroCopySend for Fault {}

impl Fault {
    /// Every fault, in counter order.
    pub const ALL: [Fault; 5] = [
        Fault::FrameSize,
        Fault::Payload,
        Fault::Header,
        Fault::Response,
        Fault::Seed,
    ];

    /// Its name in counters and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Fault::FrameSize => "frame_size",
            Fault::Payload => "payload",
            Fault::Header => "header",
            Fault::Response => "response",
            Fault::Seed => "seed",
        }
    }
}

/// What one stage made of one frame.
#[repr(C, u32)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Outcome<T> {
    /// It had nothing to work on: an earlier stage found nothing or failed.
    #[default]
    Skipped,
    /// It worked and found nothing (see each stage for what that means).
    Nothing,
    /// It produced a result.
    Done(T),
    /// Its input was bad; counted.
    Failed(Fault),
}

// SAFETY: as for Maybe.
unsafe impl<T: ZeroCopySend> ZeroCopySend for Outcome<T> {}

impl<T> From<Fault> for Outcome<T> {
    fn from(f: Fault) -> Self {
        Outcome::Failed(f)
    }
}

impl<T: Copy> Outcome<T> {
    /// The result, when there is one.
    pub fn done(&self) -> Option<T> {
        match self {
            Outcome::Done(v) => Some(*v),
            _ => None,
        }
    }

    /// Its name in JSON and reports.
    pub fn state(&self) -> &'static str {
        match self {
            Outcome::Skipped => "skipped",
            Outcome::Nothing => "nothing",
            Outcome::Done(_) => "done",
            Outcome::Failed(_) => "failed",
        }
    }
}

/// A rectangle of pixels.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ZeroCopySend)]
pub struct PixelRect {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
}

impl From<acch_core::Rect> for PixelRect {
    fn from(r: acch_core::Rect) -> Self {
        PixelRect {
            x: r.x,
            y: r.y,
            width: r.width,
            height: r.height,
        }
    }
}

impl From<PixelRect> for acch_core::Rect {
    fn from(r: PixelRect) -> Self {
        acch_core::Rect {
            x: r.x,
            y: r.y,
            width: r.width,
            height: r.height,
        }
    }
}

impl PixelRect {
    /// Pixels inside.
    pub fn area(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Whether it lies inside a `width` x `height` frame.
    pub fn fits(&self, width: u32, height: u32) -> bool {
        self.x as u64 + self.width as u64 <= width as u64
            && self.y as u64 + self.height as u64 <= height as u64
    }

    /// As `[x, y, width, height]`.
    pub fn to_array(self) -> [u32; 4] {
        [self.x, self.y, self.width, self.height]
    }
}

/// Pinhole intrinsics, pixels, and the lens distortion the pixels have.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Intrinsics {
    /// Focal length along x.
    pub fx: f64,
    /// Focal length along y.
    pub fy: f64,
    /// Principal point x.
    pub cx: f64,
    /// Principal point y.
    pub cy: f64,
    /// Distortion coefficients k1 k2 p1 p2 k3 k4 k5 k6 (OpenCV's order;
    /// unused ones 0).
    pub distortion: [f64; 8],
    /// The distortion model: 0 none, 1 plumb_bob, 2 rational_polynomial.
    pub distortion_model: u32,
}

impl Intrinsics {
    /// As `[fx, fy, cx, cy]`.
    pub fn to_array(self) -> [f64; 4] {
        [self.fx, self.fy, self.cx, self.cy]
    }

    /// From `[fx, fy, cx, cy]`, no distortion.
    pub fn from_array([fx, fy, cx, cy]: [f64; 4]) -> Self {
        Intrinsics {
            fx,
            fy,
            cx,
            cy,
            ..Default::default()
        }
    }

    /// A calibrated camera's.
    pub fn calibrated(c: &Calibration) -> Self {
        Intrinsics::from(&c.intrinsics).with_lens(c.distortion)
    }

    /// These intrinsics with the lens distortion `lens`.
    pub fn with_lens(self, lens: Distortion) -> Self {
        Intrinsics {
            distortion: lens.coefficients,
            distortion_model: match lens.model {
                DistortionModel::None => 0,
                DistortionModel::PlumbBob => 1,
                DistortionModel::RationalPolynomial => 2,
            },
            ..self
        }
    }

    /// The pixel an ideal pinhole camera with these focal lengths and
    /// principal point sees where this camera's lens put `pixel`: the
    /// seed's ray goes through it.
    pub fn undistort(&self, pixel: glam::DVec2) -> glam::DVec2 {
        let lens = self.lens();
        if lens.is_none() {
            return pixel;
        }
        let n = lens.undistort_normalised(glam::DVec2::new(
            (pixel.x - self.cx) / self.fx,
            (pixel.y - self.cy) / self.fy,
        ));
        glam::DVec2::new(n.x * self.fx + self.cx, n.y * self.fy + self.cy)
    }

    /// The lens distortion (an unknown model code reads as none).
    pub fn lens(&self) -> Distortion {
        let model = match self.distortion_model {
            1 => DistortionModel::PlumbBob,
            2 => DistortionModel::RationalPolynomial,
            _ => DistortionModel::None,
        };
        Distortion {
            model,
            coefficients: self.distortion,
        }
    }
}

impl From<&acch_capture::Intrinsics> for Intrinsics {
    fn from(k: &acch_capture::Intrinsics) -> Self {
        Intrinsics::from_array([k.fx, k.fy, k.cx, k.cy])
    }
}

/// Ground truth of a synthetic (or labelled) frame.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Truth {
    /// Elevation, degrees.
    pub theta_deg: f64,
    /// Azimuth, degrees.
    pub phi_deg: f64,
    /// Camera distance to the object centre, metres.
    pub distance_m: f64,
    /// The camera's roll about its optical axis, degrees.
    pub roll_deg: f64,
    /// `camera_from_object`, column-major 3x4 (rotation columns then
    /// translation in metres), OpenCV camera.
    pub camera_from_object: [f64; 12],
}

/// Where the arm says the camera is (its forward kinematics), sent with
/// every frame so seeding can fuse estimates over the camera's known motion.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct ArmPose {
    /// `world_from_camera` in the arm's base frame, column-major 3x4
    /// (rotation columns then translation), OpenCV camera axes.
    pub world_from_camera: [f64; 12],
}

/// What is known of a frame besides its pixels.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct FrameMeta {
    /// Frame number, strictly increasing through a run.
    pub sequence: u64,
    /// Pixels a row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// The camera's intrinsics.
    pub intrinsics: Intrinsics,
    /// Ground truth, when the source knows it.
    pub truth: Maybe<Truth>,
    /// The arm's camera pose, when known.
    pub arm: Maybe<ArmPose>,
    /// When the frame was taken, ns since the Unix epoch (the system
    /// clock at capture): the time stamp of every ROS 2 message about it.
    pub stamp_ns: u64,
}

/// When one stage saw one frame: CLOCK_MONOTONIC ns, 0 = not reached.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct StageTimes {
    /// Its input arrived (the stage woke up and took the sample; capture:
    /// the frame exists).
    pub received_ns: u64,
    /// Its output was sent.
    pub published_ns: u64,
}

/// The timing trail of one frame, carried by every header about it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Trail {
    /// When the frame was captured.
    pub captured_ns: u64,
    /// Per stage, indexed by [`StageId`].
    pub stages: [StageTimes; STAGES],
}

impl Trail {
    /// Stage `id`'s times.
    pub fn of(&self, id: StageId) -> StageTimes {
        self.stages[id as usize]
    }

    /// Captured -> seeding's result published, ns.
    pub fn end_to_end_ns(&self) -> u64 {
        self.of(StageId::Seeding)
            .published_ns
            .saturating_sub(self.captured_ns)
    }

    /// Upstream published -> stage `id` received (the hop into it), ns.
    pub fn hop_ns(&self, id: StageId) -> Option<u64> {
        let up = id.upstream()?;
        Some(
            self.of(id)
                .received_ns
                .saturating_sub(self.of(up).published_ns),
        )
    }

    /// Stage `id`'s received -> published (its compute and publishing), ns.
    pub fn process_ns(&self, id: StageId) -> u64 {
        let t = self.of(id);
        t.published_ns.saturating_sub(t.received_ns)
    }
}

/// How the frame's pixels were read by the stages that read them.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ZeroCopySend)]
pub struct FrameReads {
    /// Reads of the frame's pixels.
    pub reads: u32,
    /// Of those, reads that found the pixels at the very shared-memory
    /// location capture wrote them to (no copy).
    pub in_place: u32,
}

/// Which of a stage's two database sets a frame goes through.
#[repr(u32)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DatabaseSet {
    /// The sharp databases (the default; the only set of a run that does
    /// not choose).
    #[default]
    Sharp = 0,
    /// The databases that smooth views and frames, with the confidence
    /// trained for a worse camera: for a noisy or compressed frame, or a
    /// blurred object.
    Smoothed = 1,
}

// SAFETY: a fieldless repr(u32) enum: four bytes, no pointers.
unsafe impl ZeroCopySend for DatabaseSet {}

impl DatabaseSet {
    /// Its name in results: `sharp` or `smoothed`.
    pub fn name(self) -> &'static str {
        match self {
            DatabaseSet::Sharp => "sharp",
            DatabaseSet::Smoothed => "smoothed",
        }
    }
}

/// Why recognition sent a frame through the smoothed set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SmoothedFor {
    /// The camera's noise or JPEG blocking.
    Camera,
    /// The object blurred, measured over the sharp set's window: the
    /// frame is quantised as it is, already as blurred as the smoothed
    /// set's views.
    Blur,
    /// The sharp set found no object, or found it only under its
    /// threshold (faint) and the smoothed set found it clearly or the
    /// object is blurred.
    NotFound,
}

impl SmoothedFor {
    /// Its name in results: `camera`, `blur` or `not_found`.
    pub fn name(self) -> &'static str {
        match self {
            SmoothedFor::Camera => "camera",
            SmoothedFor::Blur => "blur",
            SmoothedFor::NotFound => "not_found",
        }
    }
}

/// What recognition measured of the frame's camera and of the object, and
/// the database set it chose for the frame by them (a run with `smoothing =
/// "auto"`; otherwise nothing measured and the sharp set).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct FrameImaging {
    /// Noise, grey levels ([`acch_core::FrameQuality::noise_sigma`]; 0: not
    /// measured).
    pub noise_sigma: f32,
    /// JPEG blocking ([`acch_core::FrameQuality::blockiness`]; 0: not
    /// measured).
    pub blockiness: f32,
    /// Sharpness over the window the sharp set found the object in
    /// ([`acch_core::QualityMeter::sharpness_within`]; 0: not measured, as
    /// on a noisy or blocky frame, with nothing found or no strong edge in
    /// the window).
    pub object_sharpness: f32,
    /// The set the later stages ran the frame through: the smoothed one
    /// for a noisy or blocky frame, a blurred object, or one the sharp set
    /// did not find.
    pub set: DatabaseSet,
}

impl FrameImaging {
    /// Why the frame went through the smoothed set; None: the sharp one.
    /// Read back from the measures recognition chose by: the camera's
    /// first, then the object's sharpness, measured only when the sharp
    /// set found the object (and then above 0: it is a mean over slope
    /// maxima, each above 0).
    pub fn smoothed_for(&self) -> Option<SmoothedFor> {
        if self.set != DatabaseSet::Smoothed {
            return None;
        }
        let camera = acch_core::FrameQuality {
            noise_sigma: self.noise_sigma,
            blockiness: self.blockiness,
            sharpness: f32::NAN,
        };
        Some(if camera.needs_smoothing() {
            SmoothedFor::Camera
        } else if self.object_sharpness > 0.0 {
            SmoothedFor::Blur
        } else {
            SmoothedFor::NotFound
        })
    }
}

/// What every header carries: the frame, its trail, its reads and its
/// imaging.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Envelope {
    /// The frame.
    pub frame: FrameMeta,
    /// When each stage saw it.
    pub trail: Trail,
    /// How its pixels were read.
    pub reads: FrameReads,
    /// The camera's imaging as recognition measured it, and the database
    /// set chosen by it.
    pub imaging: FrameImaging,
}

/// A hop's header: every header carries the [`Envelope`].
pub trait Hop {
    /// The envelope.
    fn envelope(&self) -> &Envelope;
    /// The envelope, to stamp.
    fn envelope_mut(&mut self) -> &mut Envelope;
    /// Where the frame's pixels are in shared memory, for a header whose
    /// payload is the pixels (the frame stream's); `None` for the others.
    fn pixels_at(&self) -> Option<(u64, u64)> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stage_names_round_trip() {
        for s in StageId::ALL {
            assert_eq!(StageId::from_name(s.name()), Some(s));
        }
        assert_eq!(StageId::Pose.upstream(), Some(StageId::Segmentation));
        assert_eq!(StageId::Capture.upstream(), None);
        assert_eq!(StageId::from_name("viz"), None);
    }

    #[test]
    fn rectangles_fit_only_inside_the_frame() {
        let r = PixelRect {
            x: 10,
            y: 2,
            width: 6,
            height: 5,
        };
        assert!(r.fits(16, 7));
        assert!(!r.fits(15, 7));
        assert!(!r.fits(16, 6));
        let huge = PixelRect {
            x: u32::MAX,
            width: u32::MAX,
            ..r
        };
        assert!(!huge.fits(u32::MAX, 7));
    }

    #[test]
    fn the_trail_measures_hops_and_processing() {
        let mut t = Trail {
            captured_ns: 100,
            ..Default::default()
        };
        t.stages[0] = StageTimes {
            received_ns: 100,
            published_ns: 150,
        };
        t.stages[1] = StageTimes {
            received_ns: 170,
            published_ns: 400,
        };
        t.stages[5].published_ns = 900;
        assert_eq!(t.hop_ns(StageId::Recognition), Some(20));
        assert_eq!(t.hop_ns(StageId::Capture), None);
        assert_eq!(t.process_ns(StageId::Recognition), 230);
        assert_eq!(t.end_to_end_ns(), 800);
    }

    #[test]
    fn the_seeds_ray_goes_through_the_undistorted_pixel() {
        // Barrel distortion k1 = -0.2. By hand: the ideal normalised point
        // (0.4, 0.3) has r^2 = 0.25 and radial factor 1 - 0.2 * 0.25 =
        // 0.95, so the lens images it at (0.38, 0.285), pixel (510, 382.5)
        // with f = 500 and centre (320, 240); its ideal pixel is (520, 390).
        let k = Intrinsics::from_array([500.0, 500.0, 320.0, 240.0])
            .with_lens(Distortion::plumb_bob([-0.2, 0.0, 0.0, 0.0, 0.0]));
        let ideal = k.undistort(glam::DVec2::new(510.0, 382.5));
        assert!(
            (ideal - glam::DVec2::new(520.0, 390.0)).length() < 1e-6,
            "{ideal}"
        );
        // No distortion: the pixel itself.
        let pinhole = Intrinsics::from_array([500.0, 500.0, 320.0, 240.0]);
        let p = glam::DVec2::new(510.0, 382.5);
        assert_eq!(pinhole.undistort(p), p);
        // The model survives the trip through the frame header.
        assert_eq!(k.lens().model, DistortionModel::PlumbBob);
        assert_eq!(k.lens().coefficients[0], -0.2);
    }
}
