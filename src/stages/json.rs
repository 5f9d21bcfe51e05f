//! The JSON published on zenoh: results and seeds.

use acch_ipc::{ResultMsg, StageId};
use glam::DQuat;
use serde::{Deserialize, Serialize};

/// A time stamp: CLOCK_MONOTONIC nanoseconds of the capturing machine.
#[derive(Serialize, Deserialize, Debug, Clone)]
pub struct Stamp {
    /// Always "CLOCK_MONOTONIC".
    pub clock: &'static str,
    /// Frame captured.
    pub captured_ns: u64,
    /// Result published by the seeding stage.
    pub published_ns: u64,
}

/// The JSON published at `<prefix>/<object>/seed`.
#[derive(Serialize, Debug, Clone)]
pub struct SeedJson {
    /// Object name.
    pub object: String,
    /// Frame number.
    pub sequence: u64,
    /// Time stamps.
    pub stamp: Stamp,
    /// Parent frame: the OpenCV camera frame (x right, y down, z forward).
    pub frame_id: &'static str,
    /// Child frame: the object (centre at origin, z up).
    pub child_frame_id: &'static str,
    /// Object centre in the camera frame.
    pub translation: [f64; 3],
    /// Unit of the translation.
    pub translation_unit: &'static str,
    /// camera_from_object rotation, quaternion [x, y, z, w].
    pub rotation_xyzw: [f64; 4],
    /// Row-major 6x6 covariance over (tx, ty, tz, rx, ry, rz), left
    /// perturbation in the camera frame, rotation in rad.
    pub covariance: Vec<f64>,
    /// Confidence of the 2-DOF estimate, [0, 1].
    pub confidence: f64,
}

/// Ground truth in the result (synthetic frames only).
#[derive(Serialize, Debug, Clone)]
pub struct TruthJson {
    /// Elevation, degrees.
    pub theta_deg: f64,
    /// Azimuth, degrees.
    pub phi_deg: f64,
    /// Distance, object bounding radii.
    pub distance: f64,
    /// True camera_from_object translation.
    pub translation: [f64; 3],
    /// True camera_from_object rotation [x, y, z, w].
    pub rotation_xyzw: [f64; 4],
}

/// The seeding stage's pose fused over time, in a result.
#[derive(Serialize, Debug, Clone)]
pub struct FusedJson {
    /// θ, φ degrees.
    pub view_deg: [f64; 2],
    /// Row-major 2x2 covariance of (θ, φ), degrees².
    pub view_covariance_deg2: [f64; 4],
    /// camera_from_object translation.
    pub translation: [f64; 3],
    /// camera_from_object rotation [x, y, z, w].
    pub rotation_xyzw: [f64; 4],
    /// Row-major 3x3 rotation covariance, radians².
    pub rotation_covariance: [f64; 9],
    /// What this frame's estimate did: none, started, fused, gated, restarted.
    pub outcome: &'static str,
    /// Estimates fused since the filter (re)started.
    pub fused: u64,
    /// Frames since the last fused estimate.
    pub since_update: u64,
}

/// The JSON published at `<prefix>/<object>/result`, one per frame.
#[derive(Serialize, Debug, Clone)]
pub struct ResultJson {
    /// Object name.
    pub object: String,
    /// Frame number.
    pub sequence: u64,
    /// Whether a pose is reported (estimated, rated at or above threshold,
    /// seeded).
    pub accepted: bool,
    /// Time stamps.
    pub stamp: Stamp,
    /// Whether recognition found the object.
    pub found: bool,
    /// ROI [x, y, width, height] pixels, when segmented.
    pub roi: Option<[u64; 4]>,
    /// θ, φ degrees, when estimated.
    pub estimate_deg: Option<[f64; 2]>,
    /// Confidence, when rated.
    pub confidence: Option<f64>,
    /// The seed, when accepted.
    pub seed: Option<SeedJson>,
    /// The pose fused over the frames so far, once the filter has one.
    pub fused: Option<FusedJson>,
    /// Ground truth, when the source knows it.
    pub truth: Option<TruthJson>,
    /// Per stage [received_ns, published_ns], CLOCK_MONOTONIC.
    pub trail: Vec<(String, [u64; 2])>,
}

impl ResultJson {
    /// The JSON view of a final result.
    pub fn of(object: &str, m: &ResultMsg) -> ResultJson {
        let stamp = || Stamp {
            clock: "CLOCK_MONOTONIC",
            captured_ns: m.trail.captured_ns,
            published_ns: m.trail.stages[StageId::Seeding as usize].published_ns,
        };
        let seed = (m.seeded == 1 && m.accepted == 1).then(|| SeedJson {
            object: object.to_owned(),
            sequence: m.sequence,
            stamp: stamp(),
            frame_id: "camera_optical",
            child_frame_id: "object",
            translation: m.seed_translation,
            translation_unit: "object bounding radii",
            rotation_xyzw: m.seed_rotation_xyzw,
            covariance: m.seed_covariance.iter().flatten().copied().collect(),
            confidence: m.confidence,
        });
        let truth = (m.truth.valid == 1).then(|| {
            let a = glam::DAffine3::from_cols_array(&m.truth.camera_from_object);
            TruthJson {
                theta_deg: m.truth.theta_deg,
                phi_deg: m.truth.phi_deg,
                distance: m.truth.distance,
                translation: a.translation.to_array(),
                rotation_xyzw: DQuat::from_mat3(&a.matrix3).normalize().to_array(),
            }
        });
        let fused = (m.fused.valid == 1).then(|| {
            let f = &m.fused;
            let a = glam::DAffine3::from_cols_array(&f.camera_from_object);
            FusedJson {
                view_deg: f.view_deg,
                view_covariance_deg2: f.view_covariance_deg2,
                translation: a.translation.to_array(),
                rotation_xyzw: DQuat::from_mat3(&a.matrix3).normalize().to_array(),
                rotation_covariance: f.rotation_covariance,
                outcome: ["none", "started", "fused", "gated", "restarted"]
                    .get(f.outcome as usize)
                    .copied()
                    .unwrap_or("none"),
                fused: f.fused,
                since_update: f.since_update,
            }
        });
        ResultJson {
            object: object.to_owned(),
            sequence: m.sequence,
            accepted: seed.is_some(),
            stamp: stamp(),
            found: m.found == 1,
            roi: (m.segmented == 1).then_some(m.roi),
            estimate_deg: (m.estimated == 1).then_some([m.estimate[0], m.estimate[1]]),
            confidence: (m.rated == 1).then_some(m.confidence),
            seed,
            fused,
            truth,
            trail: StageId::ALL
                .iter()
                .map(|s| {
                    let t = m.trail.stages[*s as usize];
                    (s.name().to_owned(), [t.received_ns, t.published_ns])
                })
                .collect(),
        }
    }
}
