//! The pipeline as processes: the configuration every process reads, the
//! generic stage wrapper (block on the input's event, look the frame up,
//! call the stage's pure function, publish), the five processing stages and
//! the capture source.
//!
//! Data flows one way: capture -> recognition -> segmentation -> pose ->
//! confidence -> seeding. Every result message carries the results of the
//! stages before it, so a stage reads exactly one result stream plus, if it
//! needs pixels, the frame of the same sequence from its frame history.

use acch_capture::{Background, DEFAULT_DISTANCE, Trajectory};
use acch_confidence::Model as ConfidenceModel;
use acch_core::{IndexImage, Palette, Rect, ViewDatabase};
use acch_ipc::{
    FrameHeader, FrameHistory, Ipc, Names, Qos, ResultMsg, SeedPublisher, ShmLocator, StageId,
    ZenohConfig, now_ns, pixel_format,
};
use acch_pose::{PoseEstimator, Refinement, Slice};
use acch_recognition::{CellRect, Detection, Detector, RecognitionModel};
use acch_segmentation::Segmenter;
use anyhow::{Context, Result, anyhow, bail};
use glam::{DQuat, DVec2};
use iceoryx2::prelude::EventId;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How long a stage sleeps on its input before checking for termination.
const WAIT: Duration = Duration::from_millis(200);

/// The pipeline's configuration (`pipeline.toml`); every process reads the
/// same file.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PipelineConfig {
    /// Keeps the shared-memory services of concurrent runs apart (the
    /// launcher sets its pid).
    pub instance: String,
    /// Built-in object name.
    pub object: String,
    /// View database; the launcher fills in the cached default.
    pub db: Option<PathBuf>,
    /// Where default databases are cached.
    pub cache_dir: Option<PathBuf>,
    /// `synthetic` (simulated camera) or `folder:DIR` (images, labels.csv).
    pub source: String,
    /// Background of the simulated scene.
    pub background: String,
    /// Frames to capture (0 = until stopped).
    pub frames: u64,
    /// Frame rate; 0 = free-running.
    pub fps: f64,
    /// Seed of the trajectory and the scene.
    pub seed: u64,
    /// Known camera distance to the object centre (object bounding radii);
    /// unset = from the ROI's scale against training.
    pub distance: Option<f64>,
    /// Frames each pixel-reading stage keeps to look frame N up.
    pub frame_history: usize,
    /// Width of the synthetic camera's frames, pixels.
    pub width: u32,
    /// Height of the synthetic camera's frames, pixels.
    pub height: u32,
    /// How frames reach the stages: `shm` (zero copy, the pipeline) or
    /// `copy` (the benchmark's baseline: capture writes every frame into a
    /// Unix socket per pixel-reading stage, which reads it into its own
    /// buffer).
    pub transport: String,
    /// zenoh endpoints.
    pub zenoh: ZenohConfig,
}

impl Default for PipelineConfig {
    fn default() -> Self {
        PipelineConfig {
            instance: std::process::id().to_string(),
            object: "fruitbox".into(),
            db: None,
            cache_dir: None,
            source: "synthetic".into(),
            background: "A".into(),
            frames: 300,
            fps: 30.0,
            seed: 0,
            distance: Some(DEFAULT_DISTANCE),
            frame_history: 4,
            width: 640,
            height: 480,
            transport: "shm".into(),
            zenoh: ZenohConfig::default(),
        }
    }
}

impl PipelineConfig {
    /// Reads a TOML file.
    pub fn load(path: &Path) -> Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))
    }

    /// Writes it as TOML.
    pub fn save(&self, path: &Path) -> Result<()> {
        std::fs::write(path, toml::to_string(self)?)
            .with_context(|| format!("writing {}", path.display()))
    }

    /// The run's service names.
    pub fn names(&self) -> Names {
        Names::new(&self.instance)
    }

    /// Opens this process's iceoryx2 node.
    pub fn ipc(&self, node: &str) -> Result<Ipc> {
        let qos = Qos {
            frame_history: self.frame_history.max(1),
            max_frame_bytes: self.max_frame_bytes(),
        };
        Ok(Ipc::new(self.names(), node, qos)?)
    }

    /// Largest frame, bytes (the frame service's shared memory is sized
    /// for it).
    pub fn max_frame_bytes(&self) -> usize {
        self.width.max(1) as usize * self.height.max(1) as usize * 3
    }

    /// Whether frames are copied through Unix sockets (`transport = "copy"`).
    pub fn copies_frames(&self) -> Result<bool> {
        match self.transport.as_str() {
            "shm" => Ok(false),
            "copy" => Ok(true),
            other => bail!("unknown transport '{other}': use shm or copy"),
        }
    }

    /// The synthetic camera: the default focal length (so the object has
    /// its trained size in pixels at any resolution), principal point at
    /// the centre of a `width` x `height` image.
    pub fn intrinsics(&self) -> acch_capture::Intrinsics {
        sized_intrinsics(self.width, self.height)
    }

    fn database(&self) -> Result<ViewDatabase> {
        let path = self
            .db
            .as_ref()
            .ok_or_else(|| anyhow!("the configuration names no database (db = ...)"))?;
        Ok(ViewDatabase::load(path)?)
    }
}

/// A processing stage: a pure function over the running result, the input
/// payload (mask, response) and, if it needs them, the frame's pixels.
pub trait Stage {
    /// Which stage.
    const ID: StageId;
    /// Whether it reads the frame's pixels.
    const NEEDS_FRAME: bool;
    /// Bytes of its output payload (0: header only).
    fn payload_len(&self) -> usize;
    /// Processes one frame: fills its part of `msg` and of `out`.
    fn process(&mut self, msg: &mut ResultMsg, input: &[u8], frame: Option<&[u8]>, out: &mut [u8]);
    /// Called after publishing (the seeding stage sends to zenoh here).
    fn sink(&mut self, _msg: &ResultMsg) -> Result<()> {
        Ok(())
    }
}

fn announce_ready(ipc: &Ipc, id: StageId) -> Result<()> {
    let n = ipc.control_notifier("ready")?;
    n.notify_with_custom_event_id(EventId::new(id as usize))
        .map_err(|e| anyhow!("announcing readiness: {e:?}"))?;
    Ok(())
}

/// The generic process wrapper: connect, announce readiness, then for every
/// input sample (sleeping on the input's event in between) look the frame up
/// if needed, run the stage, publish, until SIGINT/SIGTERM.
pub fn run_stage<S: Stage>(cfg: &PipelineConfig, mut stage: S) -> Result<()> {
    let id = S::ID;
    let ipc = cfg.ipc(id.name())?;
    let upstream = id
        .upstream()
        .ok_or_else(|| anyhow!("capture is not a processing stage"))?;
    let from_frames = upstream == StageId::Capture;
    let copying = cfg.copies_frames()?;
    // The copy baseline: pixels arrive on this stage's socket; the frame
    // service then only carries recognition's headers and wake-ups.
    let mut copies = if copying && S::NEEDS_FRAME {
        Some(copy::FrameReceiver::bind(
            &copy::socket_path(cfg, id),
            cfg.frame_history,
        )?)
    } else {
        None
    };
    let frames = if from_frames || (S::NEEDS_FRAME && !copying) {
        Some(ipc.frame_input(from_frames)?)
    } else {
        None
    };
    let results = if from_frames {
        None
    } else {
        Some(ipc.result_input(upstream)?)
    };
    let output = ipc.result_output(id, stage.payload_len())?;
    let mut history = FrameHistory::new(cfg.frame_history);
    let mut locator = ShmLocator::new();
    let mut out = vec![0u8; stage.payload_len()];
    announce_ready(&ipc, id)?;
    tracing::debug!("{} ready", id.name());
    let mut processed = 0u64;
    while ipc.keep_running() {
        if let Some(r) = &results {
            r.wait(WAIT)?;
        } else if let Some(f) = &frames {
            f.wait(WAIT)?;
        }
        loop {
            let mut msg;
            let received;
            if let Some(r) = &results {
                let Some(s) = r.receive()? else { break };
                received = now_ns();
                msg = *s.user_header();
                let frame = match (&mut copies, &frames) {
                    (Some(c), _) => {
                        msg.frame_reads += 1;
                        c.take(msg.sequence, WAIT)
                    }
                    (None, Some(f)) => history.get(f, msg.sequence)?.map(|f| {
                        in_place(&mut locator, &mut msg, f);
                        f.payload()
                    }),
                    (None, None) => None,
                };
                stage.process(&mut msg, s.payload(), frame, &mut out);
            } else {
                let Some(f) = frames.as_ref().map(|f| f.receive()).transpose()?.flatten() else {
                    break;
                };
                msg = ResultMsg::from_frame(f.user_header());
                let frame = if let Some(c) = &mut copies {
                    msg.frame_reads += 1;
                    // The hop ends when the copy is in this process.
                    let pixels = c.take(msg.sequence, WAIT);
                    received = now_ns();
                    pixels
                } else {
                    received = now_ns();
                    in_place(&mut locator, &mut msg, &f);
                    Some(f.payload())
                };
                stage.process(&mut msg, &[], frame, &mut out);
            }
            msg.trail.stages[id as usize].received_ns = received;
            let mut sent = msg;
            output.send(&out, |h, _| {
                msg.trail.stages[id as usize].published_ns = now_ns();
                *h = msg;
                sent = msg;
            })?;
            stage.sink(&sent)?;
            processed += 1;
        }
    }
    tracing::info!(
        "{}: {processed} frames, {} frames left the history unread",
        id.name(),
        history.dropped
    );
    Ok(())
}

/// Counts a frame read, and whether it found the pixels where capture
/// wrote them (same shared-memory file and offset: not copied).
fn in_place(locator: &mut ShmLocator, msg: &mut ResultMsg, f: &acch_ipc::FrameSample) {
    let h = f.user_header();
    msg.frame_reads += 1;
    if locator.locate(f.payload().as_ptr() as usize) == Some((h.shm_file, h.shm_offset)) {
        msg.frame_reads_in_place += 1;
    }
}

fn scale_of(cfg: &PipelineConfig, db: &ViewDatabase) -> Option<f32> {
    cfg.distance.map(|d| db.train_distance / d as f32)
}

/// Quantisation + window scan.
pub struct Recognition {
    palette: Palette,
    detector: Detector,
    index: IndexImage,
    scale: Option<f32>,
}

impl Recognition {
    /// The stage for `cfg`.
    pub fn new(cfg: &PipelineConfig, width: u32, height: u32) -> Result<Self> {
        let db = cfg.database()?;
        let model = RecognitionModel::from_database(&db)?
            .ok_or_else(|| anyhow!("the database has no recognition model"))?;
        Ok(Recognition {
            palette: db.palette.clone(),
            detector: Detector::new(model, width, height)?,
            index: IndexImage::default(),
            scale: scale_of(cfg, &db),
        })
    }
}

impl Stage for Recognition {
    const ID: StageId = StageId::Recognition;
    const NEEDS_FRAME: bool = true;
    fn payload_len(&self) -> usize {
        0
    }
    fn process(&mut self, msg: &mut ResultMsg, _: &[u8], frame: Option<&[u8]>, _: &mut [u8]) {
        let Some(rgb) = frame else { return };
        let (w, h) = (msg.width as u32, msg.height as u32);
        self.palette.quantise_into(rgb, w, h, &mut self.index);
        if let Some(d) = self.detector.detect(&self.index, self.scale) {
            msg.found = 1;
            msg.window = [d.window.x, d.window.y, d.window.width, d.window.height].map(u64::from);
            msg.cells = [d.cells.x0, d.cells.y0, d.cells.x1, d.cells.y1].map(u64::from);
            msg.detection = [
                d.score as f64,
                d.threshold as f64,
                d.scale as f64,
                d.truncated as u64 as f64,
            ];
        }
    }
}

/// Region growing from the detection; publishes the mask as its payload.
pub struct Segmentation {
    palette: Palette,
    detector: Detector,
    segmenter: Segmenter,
    index: IndexImage,
    len: usize,
}

impl Segmentation {
    /// The stage for `cfg`.
    pub fn new(cfg: &PipelineConfig, width: u32, height: u32) -> Result<Self> {
        let db = cfg.database()?;
        let model = RecognitionModel::from_database(&db)?
            .ok_or_else(|| anyhow!("the database has no recognition model"))?;
        Ok(Segmentation {
            palette: db.palette.clone(),
            detector: Detector::new(model, width, height)?,
            segmenter: Segmenter::new(width, height)?,
            index: IndexImage::default(),
            len: width as usize * height as usize,
        })
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
    const NEEDS_FRAME: bool = true;
    fn payload_len(&self) -> usize {
        self.len
    }
    fn process(&mut self, msg: &mut ResultMsg, _: &[u8], frame: Option<&[u8]>, out: &mut [u8]) {
        let (Some(rgb), 1) = (frame, msg.found) else {
            return;
        };
        let (w, h) = (msg.width as u32, msg.height as u32);
        self.palette.quantise_into(rgb, w, h, &mut self.index);
        self.detector.prepare(&self.index);
        let det = Detection {
            window: rect(msg.window),
            cells: CellRect {
                x0: msg.cells[0] as u32,
                y0: msg.cells[1] as u32,
                x1: msg.cells[2] as u32,
                y1: msg.cells[3] as u32,
            },
            score: msg.detection[0] as f32,
            threshold: msg.detection[1] as f32,
            scale: msg.detection[2] as f32,
            truncated: msg.detection[3] != 0.0,
        };
        if let Some(seg) = self.segmenter.segment(&self.index, &self.detector, &det)
            && seg.mask.len() == out.len()
        {
            out.copy_from_slice(seg.mask);
            msg.segmented = 1;
            msg.roi = [seg.roi.x, seg.roi.y, seg.roi.width, seg.roi.height].map(u64::from);
        }
    }
}

/// ACCH of the segmented ROI and the match-value response (published as
/// the payload, f32 native-endian).
pub struct Pose {
    palette: Palette,
    estimator: PoseEstimator,
    index: IndexImage,
    scale: Option<f32>,
    views: usize,
}

impl Pose {
    /// The stage for `cfg`.
    pub fn new(cfg: &PipelineConfig) -> Result<Self> {
        let db = cfg.database()?;
        Ok(Pose {
            palette: db.palette.clone(),
            scale: scale_of(cfg, &db),
            views: db.views().len(),
            estimator: PoseEstimator::new(db)?,
            index: IndexImage::default(),
        })
    }
}

impl Stage for Pose {
    const ID: StageId = StageId::Pose;
    const NEEDS_FRAME: bool = true;
    fn payload_len(&self) -> usize {
        self.views * 4
    }
    fn process(&mut self, msg: &mut ResultMsg, mask: &[u8], frame: Option<&[u8]>, out: &mut [u8]) {
        let (Some(rgb), 1) = (frame, msg.segmented) else {
            return;
        };
        let (w, h) = (msg.width as u32, msg.height as u32);
        self.palette.quantise_into(rgb, w, h, &mut self.index);
        let Some(e) = self.estimator.estimate(
            &self.index,
            Some(mask),
            rect(msg.roi),
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
        if msg.estimated == 0 || msg.accepted == 0 {
            msg.accepted = 0;
            return;
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
            }
        }
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

/// A frame source.
enum Source {
    Synthetic {
        renderer: Box<acch_capture::Renderer>,
        trajectory: Trajectory,
        frame: Box<acch_capture::Rendered>,
        seed: u64,
    },
    Folder {
        files: Vec<(PathBuf, Option<acch_capture::labels::LabelRow>)>,
        pixels: Vec<u8>,
    },
}

/// Runs the capture process: waits for the launcher's start signal, then
/// writes `cfg.frames` frames into shared memory at `cfg.fps` and stays
/// until terminated (subscribers may still hold its samples).
pub fn run_capture(cfg: &PipelineConfig) -> Result<()> {
    let ipc = cfg.ipc("capture")?;
    let output = ipc.frame_output()?;
    let start = ipc.control_listener("start")?;
    let mut source = match cfg.source.as_str() {
        "synthetic" => {
            let object = acch_capture::Object::builtin(&cfg.object)?;
            let background: Background = cfg.background.parse()?;
            let renderer = sized_renderer(
                std::sync::Arc::new(object),
                background,
                cfg.seed,
                cfg.intrinsics(),
            );
            let distance = cfg.distance.unwrap_or(DEFAULT_DISTANCE);
            let trajectory = Trajectory::new(
                cfg.seed,
                if cfg.fps > 0.0 { cfg.fps } else { 30.0 },
                distance,
            )?;
            let frame = Box::new(renderer.render(&trajectory.frame(0).view, 0));
            Source::Synthetic {
                renderer: Box::new(renderer),
                trajectory,
                frame,
                seed: cfg.seed,
            }
        }
        s if s.starts_with("folder:") => {
            let dir = PathBuf::from(&s["folder:".len()..]);
            let labels = dir.join("labels.csv");
            let files = if labels.exists() {
                acch_capture::labels::read_labels(&labels)?
                    .into_iter()
                    .map(|r| (dir.join(&r.file), Some(r)))
                    .collect::<Vec<_>>()
            } else {
                let mut v: Vec<_> = std::fs::read_dir(&dir)
                    .with_context(|| format!("reading {}", dir.display()))?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.extension().is_some_and(|x| x == "png" || x == "jpg"))
                    .map(|p| (p, None))
                    .collect();
                v.sort_by(|a, b| a.0.cmp(&b.0));
                v
            };
            if files.is_empty() {
                bail!("{} holds no images", dir.display());
            }
            Source::Folder {
                files,
                pixels: Vec::new(),
            }
        }
        other => bail!("unknown source '{other}': use synthetic or folder:DIR"),
    };
    announce_ready(&ipc, StageId::Capture)?;
    // Wait for the launcher: every subscriber is connected.
    let mut go = false;
    while !go && ipc.keep_running() {
        start.timed_wait(|_| go = true, WAIT).or_else(|e| match e {
            iceoryx2::port::listener::ListenerWaitError::InterruptSignal => Ok(0),
            e => Err(anyhow!("waiting for start: {e:?}")),
        })?;
    }
    let k = cfg.intrinsics();
    let mut locator = ShmLocator::new();
    // The copy baseline: connect to every pixel-reading stage's socket (they
    // are bound before the stages announce readiness).
    let mut copies = if cfg.copies_frames()? {
        Some(copy::FrameSender::connect(
            [StageId::Recognition, StageId::Segmentation, StageId::Pose]
                .map(|id| copy::socket_path(cfg, id))
                .as_slice(),
        )?)
    } else {
        None
    };
    let t0 = Instant::now();
    let mut i = 0u64;
    while ipc.keep_running() && (cfg.frames == 0 || i < cfg.frames) {
        if cfg.fps > 0.0 {
            let due = t0 + Duration::from_secs_f64(i as f64 / cfg.fps);
            if let Some(wait) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(wait);
            }
        }
        let started = now_ns();
        let mut header = FrameHeader {
            sequence: i,
            pixel_format: pixel_format::RGB8,
            intrinsics: [k.fx, k.fy, k.cx, k.cy],
            ..Default::default()
        };
        let pixels: &[u8] = match &mut source {
            Source::Synthetic {
                renderer,
                trajectory,
                frame,
                seed,
            } => {
                let view = trajectory.frame(i).view;
                renderer.render_into(
                    &view,
                    super::cmd::common::frame_seed(*seed, i as usize),
                    frame,
                );
                let (w, h) = frame.image.dimensions();
                (header.width, header.height) = (w as u64, h as u64);
                let t = &frame.truth;
                header.truth = acch_ipc::Truth {
                    valid: 1,
                    theta_deg: t.theta_deg,
                    phi_deg: t.phi_deg,
                    distance: t.distance,
                    camera_from_object: t.world_from_camera.inverse().to_cols_array(),
                };
                frame.image.as_raw()
            }
            Source::Folder { files, pixels } => {
                let (path, label) = &files[i as usize % files.len()];
                let img = image::open(path)
                    .with_context(|| format!("reading {}", path.display()))?
                    .to_rgb8();
                (header.width, header.height) = (img.width() as u64, img.height() as u64);
                if let Some(l) = label {
                    let view = acch_capture::ViewPose::new(l.theta_deg, l.phi_deg, l.distance)?;
                    header.truth = acch_ipc::Truth {
                        valid: 1,
                        theta_deg: l.theta_deg,
                        phi_deg: l.phi_deg,
                        distance: l.distance,
                        camera_from_object: view.camera_from_world().to_cols_array(),
                    };
                }
                *pixels = img.into_raw();
                pixels
            }
        };
        if pixels.len() > cfg.max_frame_bytes() {
            bail!(
                "frame {i} is {}x{}: larger than {}x{} (set width and height)",
                header.width,
                header.height,
                cfg.width,
                cfg.height
            );
        }
        header.stride = header.width * 3;
        // The frame exists now (a camera's exposure time stamp); rendering or
        // decoding it is the capture stage's processing time.
        let captured = now_ns();
        header.capture_ns = captured;
        header.trail.captured_ns = captured;
        header.trail.stages[0].received_ns = started;
        if let Some(tx) = &mut copies {
            // Published = the copy starts; the header follows on iceoryx2
            // with no pixels.
            header.trail.stages[0].published_ns = now_ns();
            tx.send(i, pixels)?;
            output.send(&[], |h, _| *h = header)?;
        } else {
            output.send(pixels, |h, addr| {
                let loc = locator.locate(addr).unwrap_or_default();
                (header.shm_file, header.shm_offset) = loc;
                header.trail.stages[0].published_ns = now_ns();
                *h = header;
            })?;
        }
        i += 1;
    }
    tracing::info!("capture: {i} frames sent");
    while ipc.keep_running() {
        std::thread::sleep(WAIT);
    }
    Ok(())
}

/// Frame size of the configured source (stages size their buffers).
pub fn frame_size(cfg: &PipelineConfig) -> Result<(u32, u32)> {
    if let Some(dir) = cfg.source.strip_prefix("folder:") {
        let mut first: Vec<PathBuf> = std::fs::read_dir(dir)
            .with_context(|| format!("reading {dir}"))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "png" || x == "jpg"))
            .collect();
        first.sort();
        let p = first
            .first()
            .ok_or_else(|| anyhow!("{dir} holds no images"))?;
        let (w, h) =
            image::image_dimensions(p).with_context(|| format!("reading {}", p.display()))?;
        return Ok((w, h));
    }
    Ok((cfg.width, cfg.height))
}

/// Intrinsics of a `width` x `height` synthetic camera with the default
/// focal length.
pub fn sized_intrinsics(width: u32, height: u32) -> acch_capture::Intrinsics {
    acch_capture::Intrinsics {
        width,
        height,
        cx: (width as f64 - 1.0) / 2.0,
        cy: (height as f64 - 1.0) / 2.0,
        ..Default::default()
    }
}

/// The synthetic scene's renderer with the given intrinsics.
pub fn sized_renderer(
    object: std::sync::Arc<acch_capture::Object>,
    background: Background,
    scene_seed: u64,
    intrinsics: acch_capture::Intrinsics,
) -> acch_capture::Renderer {
    acch_capture::Renderer::new(
        acch_capture::SceneConfig {
            object,
            background,
            intrinsics,
            effects: Default::default(),
        },
        scene_seed,
    )
}

/// The benchmark's copy baseline: frames written by capture into one Unix
/// stream socket per pixel-reading stage; a thread in the stage reads each
/// frame into a buffer of its own (a ring of `frame_history` buffers,
/// reused), where the stage looks frame N up.
pub mod copy {
    use super::PipelineConfig;
    use acch_ipc::StageId;
    use anyhow::{Context, Result};
    use std::collections::VecDeque;
    use std::io::{Read, Write};
    use std::os::unix::net::{UnixListener, UnixStream};
    use std::path::{Path, PathBuf};
    use std::sync::{Arc, Condvar, Mutex};
    use std::time::{Duration, Instant};

    /// The socket a stage receives its frame copies on.
    pub fn socket_path(cfg: &PipelineConfig, id: StageId) -> PathBuf {
        std::env::temp_dir().join(format!("acch-{}-{}.sock", cfg.instance, id.name()))
    }

    /// Capture's end: one connected stream per consumer.
    pub struct FrameSender {
        streams: Vec<UnixStream>,
    }

    impl FrameSender {
        /// Connects to every consumer's socket.
        pub fn connect(paths: &[PathBuf]) -> Result<Self> {
            let streams = paths
                .iter()
                .map(|p| {
                    UnixStream::connect(p).with_context(|| format!("connecting to {}", p.display()))
                })
                .collect::<Result<_>>()?;
            Ok(FrameSender { streams })
        }

        /// Writes frame `sequence` to every consumer (blocks while a
        /// consumer's socket buffer is full).
        pub fn send(&mut self, sequence: u64, pixels: &[u8]) -> Result<()> {
            let mut head = [0u8; 16];
            head[..8].copy_from_slice(&sequence.to_ne_bytes());
            head[8..].copy_from_slice(&(pixels.len() as u64).to_ne_bytes());
            for s in &mut self.streams {
                s.write_all(&head).context("writing a frame copy")?;
                s.write_all(pixels).context("writing a frame copy")?;
            }
            Ok(())
        }
    }

    #[derive(Default)]
    struct Ring {
        frames: VecDeque<(u64, Vec<u8>)>,
        spare: Vec<Vec<u8>>,
        capacity: usize,
    }

    /// A stage's end: the frames copied so far.
    pub struct FrameReceiver {
        shared: Arc<(Mutex<Ring>, Condvar)>,
        current: Vec<u8>,
        path: PathBuf,
    }

    impl FrameReceiver {
        /// Binds the stage's socket and starts the thread that accepts
        /// capture and copies every frame in.
        pub fn bind(path: &Path, capacity: usize) -> Result<Self> {
            let _ = std::fs::remove_file(path);
            let listener =
                UnixListener::bind(path).with_context(|| format!("binding {}", path.display()))?;
            let shared = Arc::new((
                Mutex::new(Ring {
                    capacity: capacity.max(1),
                    ..Default::default()
                }),
                Condvar::new(),
            ));
            let ring = shared.clone();
            std::thread::spawn(move || {
                let Ok((mut stream, _)) = listener.accept() else {
                    return;
                };
                let mut head = [0u8; 16];
                while stream.read_exact(&mut head).is_ok() {
                    let seq = u64::from_ne_bytes(head[..8].try_into().expect("8 bytes"));
                    let len = u64::from_ne_bytes(head[8..].try_into().expect("8 bytes")) as usize;
                    let mut buf = ring
                        .0
                        .lock()
                        .ok()
                        .and_then(|mut r| r.spare.pop())
                        .unwrap_or_default();
                    buf.resize(len, 0);
                    if stream.read_exact(&mut buf).is_err() {
                        return;
                    }
                    let Ok(mut r) = ring.0.lock() else { return };
                    if r.frames.len() == r.capacity
                        && let Some((_, old)) = r.frames.pop_front()
                    {
                        r.spare.push(old);
                    }
                    r.frames.push_back((seq, buf));
                    drop(r);
                    ring.1.notify_all();
                }
            });
            Ok(FrameReceiver {
                shared,
                current: Vec::new(),
                path: path.to_owned(),
            })
        }

        /// Frame `sequence` (waiting up to `timeout` for its copy to
        /// complete); older frames are released.
        pub fn take(&mut self, sequence: u64, timeout: Duration) -> Option<&[u8]> {
            let until = Instant::now() + timeout;
            let (lock, cond) = &*self.shared;
            let mut r = lock.lock().ok()?;
            loop {
                while r.frames.front().is_some_and(|(s, _)| *s < sequence) {
                    let (_, old) = r.frames.pop_front().expect("front exists");
                    r.spare.push(old);
                }
                if let Some((s, _)) = r.frames.front() {
                    if *s != sequence {
                        return None;
                    }
                    let (_, buf) = r.frames.pop_front().expect("front exists");
                    let old = std::mem::replace(&mut self.current, buf);
                    r.spare.push(old);
                    return Some(&self.current);
                }
                let left = until.checked_duration_since(Instant::now())?;
                r = cond.wait_timeout(r, left).ok()?.0;
            }
        }
    }

    impl Drop for FrameReceiver {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}
