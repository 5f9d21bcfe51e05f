//! Message types: `#[repr(C)]`, fixed size, no pointers, no padding (every
//! field is 8 bytes wide), so they live in shared memory as they are.

use iceoryx2::prelude::ZeroCopySend;

/// CLOCK_MONOTONIC now, nanoseconds (the clock of every timing trail).
pub fn now_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes into the timespec we own.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// The processes of the pipeline, in data-flow order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
    /// SE(3) seed, zenoh.
    Seeding = 5,
}

/// Number of stages.
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

    /// The stage's name on the command line and in reports.
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

/// Processes beside the pipeline that watch it (`acch run --rerun`,
/// `--record`): off the hot path, they read the same services and drop what
/// they cannot keep up with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Observer {
    /// Logs to rerun.
    Viz,
    /// Writes MCAP.
    Record,
}

impl Observer {
    /// Every observer.
    pub const ALL: [Observer; 2] = [Observer::Viz, Observer::Record];

    /// Its name on the command line (`acch stage viz`).
    pub fn name(self) -> &'static str {
        match self {
            Observer::Viz => "viz",
            Observer::Record => "record",
        }
    }

    /// Parses an observer name.
    pub fn from_name(name: &str) -> Option<Observer> {
        Self::ALL.into_iter().find(|o| o.name() == name)
    }

    /// The event id it announces readiness with (after the stages' ids).
    pub fn ready_id(self) -> usize {
        STAGES + self as usize
    }
}

/// When one stage saw one frame: CLOCK_MONOTONIC ns, 0 = not reached.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct StageTimes {
    /// Its input arrived (the stage woke up and took the sample).
    pub received_ns: u64,
    /// Its output was sent.
    pub published_ns: u64,
}

/// The timing trail of one frame, carried by every message about it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Trail {
    /// Exposure time (start of capture / rendering).
    pub captured_ns: u64,
    /// Per stage, indexed by [`StageId`] (capture: received = frame ready).
    pub stages: [StageTimes; STAGES],
}

/// Pixel formats of a frame.
pub mod pixel_format {
    /// Packed 8-bit RGB, 3 bytes a pixel.
    pub const RGB8: u64 = 1;
}

/// Ground truth of a synthetic (or labelled) frame.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Truth {
    /// 1 when the fields below are valid.
    pub valid: u64,
    /// Elevation, degrees.
    pub theta_deg: f64,
    /// Azimuth, degrees.
    pub phi_deg: f64,
    /// Camera distance to the object centre (object bounding radii).
    pub distance: f64,
    /// `camera_from_object` (= camera_from_world: object at the origin),
    /// column-major 3x4 (rotation columns then translation), OpenCV camera.
    pub camera_from_object: [f64; 12],
}

/// Where the arm says the camera is (its forward kinematics), sent with
/// every frame so later stages can fuse estimates over the camera's known
/// motion.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct ArmPose {
    /// 1 when the arm reported a pose for this frame.
    pub valid: u64,
    /// `world_from_camera` in the arm's base frame, column-major 3x4
    /// (rotation columns then translation), OpenCV camera axes.
    pub world_from_camera: [f64; 12],
}

/// The pose fused over time by the seeding stage (estimates accepted so
/// far, carried through the arm's known motion).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct Fused {
    /// 1 when the filter holds a pose (after its first accepted estimate).
    pub valid: u64,
    /// What this frame's estimate did to the filter: 0 none (no accepted
    /// estimate), 1 started it, 2 fused, 3 gated as an outlier, 4 restarted
    /// it from agreeing outliers.
    pub outcome: u64,
    /// Fused θ, φ (degrees).
    pub view_deg: [f64; 2],
    /// Row-major 2x2 covariance of (θ, φ), degrees².
    pub view_covariance_deg2: [f64; 4],
    /// Fused `camera_from_object`, column-major 3x4.
    pub camera_from_object: [f64; 12],
    /// Row-major 3x3 rotation covariance, radians² (camera frame).
    pub rotation_covariance: [f64; 9],
    /// Estimates fused since the filter (re)started.
    pub fused: u64,
    /// Frames predicted since the last fused estimate.
    pub since_update: u64,
}

/// The user header of a frame sample; the pixels are the `[u8]` payload.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct FrameHeader {
    /// Frame number, from 0, strictly increasing.
    pub sequence: u64,
    /// CLOCK_MONOTONIC ns at capture.
    pub capture_ns: u64,
    /// Pixels a row.
    pub width: u64,
    /// Rows.
    pub height: u64,
    /// Bytes a row.
    pub stride: u64,
    /// One of [`pixel_format`].
    pub pixel_format: u64,
    /// Camera intrinsics fx, fy, cx, cy (pixels).
    pub intrinsics: [f64; 4],
    /// Ground truth when known.
    pub truth: Truth,
    /// The arm's camera pose when known.
    pub arm: ArmPose,
    /// Where the capture process wrote the pixels: hash of the shared-memory
    /// file name and the offset inside it (see [`crate::ShmLocator`]);
    /// readers compare with where they find them.
    pub shm_file: u64,
    /// Offset of the pixels in that file.
    pub shm_offset: u64,
    /// Timing trail (capture filled).
    pub trail: Trail,
}

/// The result of the stages so far on one frame, keyed by sequence: every
/// stage copies its input's result, fills its part and publishes it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
pub struct ResultMsg {
    /// Frame number.
    pub sequence: u64,
    /// Frame size.
    pub width: u64,
    /// Frame size.
    pub height: u64,
    /// Intrinsics fx, fy, cx, cy.
    pub intrinsics: [f64; 4],
    /// Ground truth of the frame.
    pub truth: Truth,
    /// The arm's camera pose.
    pub arm: ArmPose,
    /// 1 when recognition found the object.
    pub found: u64,
    /// Detection window x, y, width, height (pixels).
    pub window: [u64; 4],
    /// Detection window in cells x0, y0, x1, y1.
    pub cells: [u64; 4],
    /// Detection score, threshold, scale; truncated (1/0).
    pub detection: [f64; 4],
    /// Side in cells of the scan's window, before it was cut to the frame.
    pub window_cells: u64,
    /// Segmentation's search area in cells x0, y0, x1, y1: recognition's
    /// payload holds its colour counts (and the ring's sums) after the
    /// indices.
    pub search_cells: [u64; 4],
    /// 1 when segmentation produced a mask.
    pub segmented: u64,
    /// ROI (mask bounding box) x, y, width, height.
    pub roi: [u64; 4],
    /// 1 when the pose stage produced an estimate.
    pub estimated: u64,
    /// θ, φ (deg), best match value, scale.
    pub estimate: [f64; 4],
    /// Index of the best view.
    pub best_view: u64,
    /// 1 when rated by the confidence network.
    pub rated: u64,
    /// Confidence in [0, 1].
    pub confidence: f64,
    /// 1 when accepted (estimated and, when rated, accepted).
    pub accepted: u64,
    /// 1 when a seed was made.
    pub seeded: u64,
    /// Seed translation (camera frame).
    pub seed_translation: [f64; 3],
    /// Seed rotation quaternion x, y, z, w (camera_from_object).
    pub seed_rotation_xyzw: [f64; 4],
    /// Seed covariance, row-major 6x6 over (tx, ty, tz, rx, ry, rz).
    pub seed_covariance: [[f64; 6]; 6],
    /// The pose fused over time (seeding stage).
    pub fused: Fused,
    /// Frame reads by stages from shared memory.
    pub frame_reads: u64,
    /// Of those, reads that found the pixels at the very shared-memory
    /// location capture wrote them to (no copy).
    pub frame_reads_in_place: u64,
    /// Timing trail.
    pub trail: Trail,
}

impl ResultMsg {
    /// The result skeleton of a frame.
    pub fn from_frame(h: &FrameHeader) -> ResultMsg {
        ResultMsg {
            sequence: h.sequence,
            width: h.width,
            height: h.height,
            intrinsics: h.intrinsics,
            truth: h.truth,
            arm: h.arm,
            trail: h.trail,
            ..Default::default()
        }
    }
}
