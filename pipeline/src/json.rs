//! The JSON view of a final result and of its seed, as published on zenoh
//! (`<prefix>/<object>/result`, `.../seed`) and recorded to MCAP. The views
//! borrow from the result ([`ResultJson::of`]) and are written into a
//! reused buffer ([`JsonWriter`]), so publishing a frame allocates nothing
//! of ours.

use crate::stages::Seeded;
use crate::wire::{Hop, STAGES, SmoothedFor, StageId};
use glam::DQuat;
use serde::Serialize;

/// A time stamp: CLOCK_MONOTONIC nanoseconds of the capturing machine.
#[derive(Serialize, Debug, Clone, Copy)]
pub struct Stamp {
    /// Always "CLOCK_MONOTONIC".
    pub clock: &'static str,
    /// Frame captured.
    pub captured_ns: u64,
    /// Result published by the seeding stage.
    pub published_ns: u64,
    /// Frame captured, ns since the Unix epoch: the stamp of its ROS 2
    /// messages.
    pub wall_ns: u64,
}

/// The unit every translation and distance of a result is in.
pub const TRANSLATION_UNIT: &str = "m";

/// The JSON published at `<prefix>/<object>/seed`.
#[derive(Serialize, Debug, Clone)]
pub struct SeedJson<'a> {
    /// Object name.
    pub object: &'a str,
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
    pub covariance: &'a [f64],
    /// Confidence of the 2-DOF estimate, [0, 1].
    pub confidence: f32,
}

/// Ground truth in the result (synthetic frames only).
#[derive(Serialize, Debug, Clone)]
pub struct TruthJson {
    /// Elevation, degrees.
    pub theta_deg: f64,
    /// Azimuth, degrees.
    pub phi_deg: f64,
    /// Distance to the object centre.
    pub distance: f64,
    /// The camera's roll about its optical axis, degrees.
    pub roll_deg: f64,
    /// True camera_from_object translation.
    pub translation: [f64; 3],
    /// Unit of the distance and the translation.
    pub translation_unit: &'static str,
    /// True camera_from_object rotation [x, y, z, w].
    pub rotation_xyzw: [f64; 4],
}

/// The arm's camera pose in its base frame (`world_from_camera`, OpenCV
/// camera axes), in a result.
#[derive(Serialize, Debug, Clone)]
pub struct ArmJson {
    /// Camera position.
    pub translation: [f64; 3],
    /// Unit of the translation.
    pub translation_unit: &'static str,
    /// Camera orientation [x, y, z, w].
    pub rotation_xyzw: [f64; 4],
}

/// The frame's imaging as recognition measured it, in a result of a run
/// that chooses the database set per frame (`smoothing = "auto"`).
#[derive(Serialize, Debug, Clone)]
pub struct ImagingJson {
    /// Noise, grey levels.
    pub noise_sigma: f32,
    /// JPEG blocking (about 1 uncompressed).
    pub blockiness: f32,
    /// Sharpness over the object's window (about 0.2 blurred by 2 px, 0.5
    /// at a one-pixel edge); None: not measured (a noisy or blocky frame,
    /// nothing found, no strong edge in the window).
    pub object_sharpness: Option<f32>,
    /// The databases the frame went through: sharp or smoothed.
    pub set: &'static str,
    /// Why smoothed: `camera` (noise or JPEG blocking), `blur` (the object)
    /// or `not_found` (by the sharp databases); None: sharp.
    pub smoothed_for: Option<&'static str>,
}

/// The seeding stage's pose fused over time, in a result.
#[derive(Serialize, Debug, Clone)]
pub struct FusedJson<'a> {
    /// θ, φ degrees.
    pub view_deg: [f64; 2],
    /// Row-major 2x2 covariance of (θ, φ), degrees².
    pub view_covariance_deg2: [f64; 4],
    /// camera_from_object translation.
    pub translation: [f64; 3],
    /// Unit of the translation.
    pub translation_unit: &'static str,
    /// camera_from_object rotation [x, y, z, w].
    pub rotation_xyzw: [f64; 4],
    /// Row-major 3x3 rotation covariance, radians².
    pub rotation_covariance: &'a [f64],
    /// Row-major 3x3 translation covariance, m² (the last fused seed's,
    /// carried through the motion).
    pub translation_covariance: &'a [f64],
    /// What this frame's estimate did: none, started, fused, gated, restarted.
    pub outcome: &'static str,
    /// Estimates fused since the filter (re)started.
    pub fused: u32,
    /// Frames since the last fused estimate.
    pub since_update: u32,
}

/// The JSON published at `<prefix>/<object>/result`, one per frame.
#[derive(Serialize, Debug, Clone)]
pub struct ResultJson<'a> {
    /// Object name.
    pub object: &'a str,
    /// Frame number.
    pub sequence: u64,
    /// Whether a pose is reported: estimated, accepted by the confidence
    /// stage (rated at or above the threshold, no close rival, no broad
    /// crest in azimuth, not misplaced, not faint), seeded. What a robot
    /// acts on.
    pub accepted: bool,
    /// The confidence stage's verdict: accepted, rejected, unrated (the
    /// database has no network), skipped (nothing estimated) or failed.
    pub rating: &'static str,
    /// The network's confidence, when rated.
    pub confidence: Option<f32>,
    /// The threshold it was held against, when rated.
    pub threshold: Option<f32>,
    /// The best match beyond 20° of the estimate's azimuth or 10° of its
    /// elevation over the best,
    /// when rated: above `max_rival` the estimate is rejected as
    /// ambiguous, whatever its confidence.
    pub rival: Option<f32>,
    /// The largest rival accepted, when rated.
    pub max_rival: Option<f32>,
    /// The span in azimuth of the views about the estimate that match
    /// within 2 % of it, degrees, when rated: at or above
    /// `phi_plateau_limit_deg` the estimate is rejected, whatever its
    /// confidence (the truth may lie farther away than the tolerance).
    pub phi_plateau_deg: Option<f32>,
    /// The narrowest plateau rejected, when rated.
    pub phi_plateau_limit_deg: Option<f32>,
    /// How much more of the region's coloured area a view 20-60° from the
    /// estimate in azimuth holds in place (on its colour map) than the
    /// estimate's view, when rated and weighed (null too for a database
    /// without colour maps, or a region that could not be placed).
    pub map_rival: Option<f32>,
    /// The largest map rival accepted, when rated.
    pub max_map_rival: Option<f32>,
    /// Whether the estimate was rejected as misplaced, when rated: its map
    /// rival above `max_map_rival` (or not measurable), whatever its
    /// confidence.
    pub misplaced: Option<bool>,
    /// Recognition's score for the object's window over its threshold,
    /// when rated and the region was found by recognition.
    pub detection_margin: Option<f32>,
    /// The best view's match value, when rated.
    pub match_value: Option<f32>,
    /// The least detection margin an accepted estimate has, when rated
    /// ([`acch_confidence::MIN_ACCEPTED_DETECTION_MARGIN`]): the faint
    /// rule's bars travel with every verdict, so a reader judges it by the
    /// pipeline's own numbers.
    pub min_accepted_detection_margin: Option<f32>,
    /// Below this detection margin... ([`acch_confidence::MIN_CLEAR_DETECTION_MARGIN`])
    pub min_clear_detection_margin: Option<f32>,
    /// ...and this best match value an estimate is faint
    /// ([`acch_confidence::MIN_CLEAR_MATCH_VALUE`]).
    pub min_clear_match_value: Option<f32>,
    /// Whether the estimate was rejected as faint, when rated: detection
    /// margin below [`acch_confidence::MIN_ACCEPTED_DETECTION_MARGIN`] (under
    /// recognition's threshold), or below
    /// [`acch_confidence::MIN_CLEAR_DETECTION_MARGIN`] with a match value
    /// below [`acch_confidence::MIN_CLEAR_MATCH_VALUE`], whatever its
    /// confidence (the object may not be in view).
    pub faint: Option<bool>,
    /// How the shape took part, when rated: 1 it chose the estimate (its
    /// rules judged it), 2 it fitted the colours' estimate (the colour
    /// rules judged it, with its contour on the region's edge), 0 none.
    pub verified: Option<u32>,
    /// Share of the fitted contour on the region's edge, when verified.
    pub region_edge: Option<f32>,
    /// The least share accepted, when verified.
    pub min_region_edge: Option<f32>,
    /// The fitted silhouette against the region (intersection over
    /// union), when verified.
    pub overlap: Option<f32>,
    /// The least overlap accepted, when verified.
    pub min_overlap: Option<f32>,
    /// The fit's score over its rival's (the best candidate beyond 1.75
    /// failure tolerances and not below `min_theta_deg`), when verified
    /// (null: no such candidate).
    pub shape_margin: Option<f32>,
    /// The least margin accepted, when verified.
    pub min_shape_margin: Option<f32>,
    /// Share of the fitted contour in the frame, when verified.
    pub in_frame: Option<f32>,
    /// The least share accepted, when verified and recognition found the
    /// region (a given mask needs none).
    pub min_in_frame: Option<f32>,
    /// The lowest elevation accepted for a pose the shape chose, degrees
    /// (the database's lowest view less 5°), when it chose it.
    pub min_theta_deg: Option<f32>,
    /// The farthest a pose the shape chose may place the object, metres
    /// (1.6 times the training distance, or the arm's), when it chose it
    /// and the distance is known.
    pub max_distance_m: Option<f32>,
    /// The object's pose the shape fitted, when verified: camera from
    /// object, translation (metres) and rotation (x, y, z, w).
    pub fitted_pose: Option<([f32; 3], [f32; 4])>,
    /// Time stamps.
    pub stamp: Stamp,
    /// Whether recognition found the object.
    pub found: bool,
    /// ROI [x, y, width, height] pixels, when segmented.
    pub roi: Option<[u32; 4]>,
    /// θ, φ degrees, when estimated.
    pub estimate_deg: Option<[f32; 2]>,
    /// The camera's roll about its optical axis, degrees, when estimated
    /// (0 unless `estimate.roll_search_deg` > 0).
    pub roll_deg: Option<f32>,
    /// The seed, when accepted.
    pub seed: Option<SeedJson<'a>>,
    /// The pose fused over the frames so far, once the filter has one.
    pub fused: Option<FusedJson<'a>>,
    /// Ground truth, when the source knows it.
    pub truth: Option<TruthJson>,
    /// The arm's camera pose the frame came with, when known.
    pub arm: Option<ArmJson>,
    /// The frame's measured imaging and the databases chosen by it, when
    /// the run chooses.
    pub imaging: Option<ImagingJson>,
    /// Per stage [received_ns, published_ns], CLOCK_MONOTONIC.
    pub trail: [(&'static str, [u64; 2]); STAGES],
}

/// A rotation matrix's quaternion, [x, y, z, w].
fn quaternion(camera_from_object: &[f64; 12]) -> ([f64; 3], [f64; 4]) {
    let a = glam::DAffine3::from_cols_array(camera_from_object);
    (
        a.translation.to_array(),
        DQuat::from_mat3(&a.matrix3).normalize().to_array(),
    )
}

impl<'a> ResultJson<'a> {
    /// The JSON view of final result `m` of `object`.
    pub fn of(object: &'a str, m: &'a Seeded) -> Self {
        let e = m.envelope();
        let stamp = Stamp {
            clock: "CLOCK_MONOTONIC",
            captured_ns: e.trail.captured_ns,
            published_ns: e.trail.of(StageId::Seeding).published_ns,
            wall_ns: e.frame.stamp_ns,
        };
        let verdict = m.rating().verdict();
        let seed = m
            .seeding
            .seed
            .done()
            .filter(|_| m.accepted())
            .map(|_| SeedJson {
                object,
                sequence: e.frame.sequence,
                stamp,
                frame_id: "camera_optical",
                child_frame_id: "object",
                translation: seed_of(m).translation,
                translation_unit: TRANSLATION_UNIT,
                rotation_xyzw: seed_of(m).rotation_xyzw,
                covariance: seed_covariance(m),
                confidence: verdict.map_or(0.0, |v| v.confidence),
            });
        let truth = e.frame.truth.get().map(|t| {
            let (translation, rotation_xyzw) = quaternion(&t.camera_from_object);
            TruthJson {
                roll_deg: t.roll_deg,
                theta_deg: t.theta_deg,
                phi_deg: t.phi_deg,
                distance: t.distance_m,
                translation,
                translation_unit: TRANSLATION_UNIT,
                rotation_xyzw,
            }
        });
        let fused = match &m.seeding.fused {
            crate::wire::Maybe::Present(f) => {
                let (translation, rotation_xyzw) = quaternion(&f.camera_from_object);
                Some(FusedJson {
                    view_deg: f.view_deg,
                    view_covariance_deg2: f.view_covariance_deg2,
                    translation,
                    translation_unit: TRANSLATION_UNIT,
                    rotation_xyzw,
                    rotation_covariance: &f.rotation_covariance,
                    translation_covariance: &f.translation_covariance,
                    outcome: m.seeding.fusion.name(),
                    fused: f.fused,
                    since_update: f.since_update,
                })
            }
            crate::wire::Maybe::Absent => None,
        };
        ResultJson {
            object,
            sequence: e.frame.sequence,
            accepted: m.accepted(),
            rating: m.rating().state(),
            confidence: verdict.map(|v| v.confidence),
            threshold: verdict.map(|v| v.threshold),
            rival: verdict.map(|v| v.rival),
            max_rival: verdict.map(|v| v.max_rival),
            phi_plateau_deg: verdict.map(|v| v.phi_plateau_deg),
            phi_plateau_limit_deg: verdict.map(|v| v.phi_plateau_limit_deg),
            map_rival: verdict.map(|v| v.map_rival).filter(|r| r.is_finite()),
            max_map_rival: verdict.map(|v| v.max_map_rival),
            misplaced: verdict.map(|v| v.misplaced()),
            detection_margin: verdict
                .map(|v| v.detection_margin)
                .filter(|m| m.is_finite()),
            match_value: verdict.map(|v| v.match_value),
            faint: verdict.map(|v| v.faint()),
            min_accepted_detection_margin: verdict
                .map(|_| acch_confidence::MIN_ACCEPTED_DETECTION_MARGIN),
            min_clear_detection_margin: verdict
                .map(|_| acch_confidence::MIN_CLEAR_DETECTION_MARGIN),
            min_clear_match_value: verdict.map(|_| acch_confidence::MIN_CLEAR_MATCH_VALUE),
            verified: verdict.map(|v| v.verified),
            region_edge: verdict.filter(|v| v.verified > 0).map(|v| v.region_edge),
            min_region_edge: verdict
                .filter(|v| v.verified > 0)
                .map(|v| v.min_region_edge),
            overlap: verdict.filter(|v| v.verified > 0).map(|v| v.overlap),
            min_overlap: verdict.filter(|v| v.verified > 0).map(|v| v.min_overlap),
            shape_margin: verdict
                .filter(|v| v.verified > 0)
                .map(|v| v.shape_margin)
                .filter(|m| m.is_finite()),
            min_shape_margin: verdict
                .filter(|v| v.verified > 0)
                .map(|v| v.min_shape_margin),
            in_frame: verdict.filter(|v| v.verified > 0).map(|v| v.in_frame),
            min_in_frame: verdict
                .filter(|v| v.verified > 0 && v.detection_margin.is_finite())
                .map(|v| v.min_in_frame),
            min_theta_deg: verdict
                .filter(|v| v.verified == 1 && v.min_theta_deg.is_finite())
                .map(|v| v.min_theta_deg),
            max_distance_m: verdict
                .filter(|v| v.verified == 1 && v.max_distance_m.is_finite())
                .map(|v| v.max_distance_m),
            fitted_pose: m
                .pose()
                .done()
                .and_then(|p| p.shape.done())
                .map(|f| (f.translation_m, f.rotation)),
            stamp,
            found: m.detection().done().is_some(),
            roi: m.region().done().map(|r| r.to_array()),
            estimate_deg: m.pose().done().map(|p| [p.theta_deg, p.phi_deg]),
            roll_deg: m.pose().done().map(|p| p.roll_deg),
            seed,
            fused,
            truth,
            arm: e.frame.arm.get().map(|a| {
                let (translation, rotation_xyzw) = quaternion(&a.world_from_camera);
                ArmJson {
                    translation,
                    translation_unit: TRANSLATION_UNIT,
                    rotation_xyzw,
                }
            }),
            // Zero: not measured (blockiness is about 1 when it is).
            imaging: (e.imaging.blockiness > 0.0).then(|| ImagingJson {
                noise_sigma: e.imaging.noise_sigma,
                blockiness: e.imaging.blockiness,
                object_sharpness: (e.imaging.object_sharpness > 0.0)
                    .then_some(e.imaging.object_sharpness),
                set: e.imaging.set.name(),
                smoothed_for: e.imaging.smoothed_for().map(SmoothedFor::name),
            }),
            trail: StageId::ALL.map(|s| {
                let t = e.trail.of(s);
                (s.name(), [t.received_ns, t.published_ns])
            }),
        }
    }
}

fn seed_of(m: &Seeded) -> crate::stages::SeedPose {
    m.seed().unwrap_or_default()
}

fn seed_covariance(m: &Seeded) -> &[f64] {
    match &m.seeding.seed {
        crate::wire::Outcome::Done(s) => s.covariance.as_flattened(),
        _ => &[],
    }
}

/// Writes results and seeds as JSON into buffers it keeps: after the first
/// frames no allocation.
#[derive(Default)]
pub struct JsonWriter {
    result: Vec<u8>,
    seed: Vec<u8>,
}

impl JsonWriter {
    /// Writes `m`'s result and, when accepted, its seed; returns the
    /// result's JSON and the seed's.
    pub fn write(
        &mut self,
        object: &str,
        m: &Seeded,
    ) -> Result<(&[u8], Option<&[u8]>), serde_json::Error> {
        let r = ResultJson::of(object, m);
        self.result.clear();
        serde_json::to_writer(&mut self.result, &r)?;
        let seed = match &r.seed {
            Some(s) => {
                self.seed.clear();
                serde_json::to_writer(&mut self.seed, s)?;
                Some(&self.seed[..])
            }
            None => None,
        };
        Ok((&self.result, seed))
    }
}

/// The zenoh sink of the seeding stage: every result at
/// `<prefix>/<object>/result`, every accepted seed at `.../seed`, and with
/// `[ros2] enabled` the ROS 2 topics on the same session.
pub struct ZenohSink {
    object: String,
    seeds: acch_ipc::Publisher,
    results: acch_ipc::Publisher,
    json: JsonWriter,
    ros2: Option<crate::ros2::Ros2Out>,
    // The session outlives its publishers.
    _session: zenoh::Session,
}

impl ZenohSink {
    /// Opens a session on `cfg`'s zenoh endpoints and declares its object's
    /// publishers.
    pub fn open(cfg: &crate::PipelineConfig) -> Result<Self, crate::observe::ObserveError> {
        let session = acch_ipc::open_session(&cfg.zenoh.listen, &cfg.zenoh.connect)
            .map_err(acch_ipc::IpcError::from)?;
        Self::on_session(session, cfg, &cfg.object.name, crate::ros2::Ros2Role::Only)
    }

    /// The sink of `object` on an open session (several objects share
    /// one), its ROS 2 node, if enabled, in `role`.
    pub fn on_session(
        session: zenoh::Session,
        cfg: &crate::PipelineConfig,
        object: &str,
        role: crate::ros2::Ros2Role,
    ) -> Result<Self, crate::observe::ObserveError> {
        let config = &cfg.zenoh;
        let publisher = |key: String| {
            acch_ipc::Publisher::declare(&session, &key).map_err(acch_ipc::IpcError::from)
        };
        Ok(ZenohSink {
            seeds: publisher(format!("{}/{object}/seed", config.prefix))?,
            results: publisher(format!("{}/{object}/result", config.prefix))?,
            object: object.to_owned(),
            json: JsonWriter::default(),
            ros2: cfg
                .ros2
                .enabled
                .then(|| crate::ros2::Ros2Out::declare(&session, &cfg.ros2, object, role))
                .transpose()?,
            _session: session,
        })
    }
}

impl ZenohSink {
    /// Moves the ROS 2 image publisher, if configured, to a thread reading
    /// the frame stream (the seeding process has no frames of its own).
    pub fn spawn_images(
        &mut self,
        cfg: &crate::PipelineConfig,
    ) -> Option<std::thread::JoinHandle<Result<(), crate::observe::ObserveError>>> {
        let images = self.ros2.as_mut()?.images.take()?;
        Some(images.spawn(cfg))
    }
}

impl crate::observe::Observe for ZenohSink {
    fn frame(
        &mut self,
        h: &crate::FrameHeader,
        pixels: &[u8],
    ) -> Result<(), crate::observe::ObserveError> {
        match self.ros2.as_mut().and_then(|r| r.images.as_mut()) {
            Some(images) => images.frame(h, pixels),
            None => Ok(()),
        }
    }

    fn result(&mut self, m: &Seeded) -> Result<(), crate::observe::ObserveError> {
        let (result, seed) = self.json.write(&self.object, m)?;
        if let Some(seed) = seed {
            self.seeds.put(seed).map_err(acch_ipc::IpcError::from)?;
        }
        self.results.put(result).map_err(acch_ipc::IpcError::from)?;
        if let Some(ros2) = &mut self.ros2 {
            ros2.publish(m)?;
        }
        Ok(())
    }
}

/// Writes every result as one line of JSON into a file (`acch run
/// --results FILE.jsonl`).
pub struct JsonLines {
    path: std::path::PathBuf,
    file: std::io::BufWriter<std::fs::File>,
    object: String,
    json: JsonWriter,
}

impl JsonLines {
    /// Creates `path` for results of `object`.
    pub fn create(
        path: &std::path::Path,
        object: &str,
    ) -> Result<Self, crate::observe::ObserveError> {
        let file =
            std::fs::File::create(path).map_err(|source| crate::observe::ObserveError::Io {
                path: path.to_owned(),
                source,
            })?;
        Ok(JsonLines {
            path: path.to_owned(),
            file: std::io::BufWriter::new(file),
            object: object.to_owned(),
            json: JsonWriter::default(),
        })
    }

    /// Writes what is buffered.
    pub fn flush(&mut self) -> Result<(), crate::observe::ObserveError> {
        use std::io::Write;
        self.file
            .flush()
            .map_err(|source| crate::observe::ObserveError::Io {
                path: self.path.clone(),
                source,
            })
    }
}

impl crate::observe::Observe for JsonLines {
    fn result(&mut self, m: &Seeded) -> Result<(), crate::observe::ObserveError> {
        use std::io::Write;
        let (line, _) = self.json.write(&self.object, m)?;
        self.file
            .write_all(line)
            .and_then(|_| self.file.write_all(b"\n"))
            .map_err(|source| crate::observe::ObserveError::Io {
                path: self.path.clone(),
                source,
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The recording's result schema (what a Foxglove viewer checks
    /// message paths against) declares every field a result carries.
    #[test]
    fn the_recorded_result_schema_declares_every_field_of_a_result() {
        let mut writer = JsonWriter::default();
        let (json, _) = writer.write("fruitbox", &Seeded::default()).unwrap();
        let result: serde_json::Value = serde_json::from_slice(json).unwrap();
        let schema: serde_json::Value = serde_json::from_str(acch_record::RESULT_SCHEMA).unwrap();
        let declared = schema["properties"].as_object().unwrap();
        let fields = result.as_object().unwrap();
        assert!(fields.contains_key("min_theta_deg"), "{fields:?}");
        assert!(fields.contains_key("max_distance_m"), "{fields:?}");
        // The trail (a stage name and two times per stage) and the fitted
        // pose (a translation and a quaternion) have no single item type,
        // which Foxglove needs: the schema describes them and does not
        // list them.
        let missing: Vec<&String> = fields
            .keys()
            .filter(|k| !["trail", "fitted_pose"].contains(&k.as_str()))
            .filter(|k| !declared.contains_key(*k))
            .collect();
        assert!(missing.is_empty(), "undeclared: {missing:?}");
    }
}
