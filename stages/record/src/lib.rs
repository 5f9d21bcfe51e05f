//! Records acch frames and results to MCAP and reads them back for replay.
//!
//! Channels (every message's MCAP `sequence` is the frame number, its log
//! and publish time the capture time mapped to the Unix epoch):
//!
//! | topic | schema | encoding |
//! | --- | --- | --- |
//! | `/camera/image` | `foxglove.RawImage` (rgb8) | protobuf |
//! | `/acch/frame` | `acch.Frame`: sequence, capture time, intrinsics, truth | JSON |
//! | `/acch/mask` | `foxglove.RawImage` (mono8, 0 = background, 255 = object) | protobuf |
//! | `/acch/response` | `acch.Response`: match value per database view | JSON |
//! | `/acch/result` | `acch.Result`: the result published on zenoh | JSON |
//! | `/acch/seed` | `foxglove.PoseInFrame` (camera_from_object) | protobuf |
//! | `/camera/calibration` | `foxglove.CameraCalibration` (the frame's intrinsics) | protobuf |
//! | `/acch/overlay` | `foxglove.ImageAnnotations`: detection window, ROI, seed and true axes projected | protobuf |
//! | `/acch/mask/overlay` | `foxglove.ImageAnnotations`: the mask as translucent row runs | protobuf |
//! | `/tf` | `foxglove.FrameTransforms`: `seed`, `fused`, `truth` in `camera_optical` | protobuf |
//! | `/acch/latency` | `acch.Latency`: ms from capture to each stage's publishing | JSON |
//!
//! The overlays, transforms and latencies are for viewers (the Foxglove
//! layout, `docs/foxglove-layout.json`); a replay reads only frames.
//!
//! Pixels are written once into the record (no base64, no compression): the
//! recorder runs beside the pipeline on the same cores and must stay cheap.

pub mod proto;
mod schema;

pub use schema::{FrameInfo, FrameTruth, LatencyJson, RESULT_SCHEMA, ResponseJson};

use mcap::sans_io::LinearReaderOptions;
use mcap::{McapError, WriteOptions, records::MessageHeader};
use proto::{FrameTransform, PointsAnnotation, PointsKind, RawImageHeader, TextAnnotation};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, BufWriter, Seek, Write};
use std::path::{Path, PathBuf};

/// Topic of the camera frames.
pub const TOPIC_IMAGE: &str = "/camera/image";
/// Topic of the per-frame metadata (intrinsics, ground truth).
pub const TOPIC_FRAME: &str = "/acch/frame";
/// Topic of the segmentation masks.
pub const TOPIC_MASK: &str = "/acch/mask";
/// Topic of the match-value responses.
pub const TOPIC_RESPONSE: &str = "/acch/response";
/// Topic of the final results.
pub const TOPIC_RESULT: &str = "/acch/result";
/// Topic of the 6-DOF seeds.
pub const TOPIC_SEED: &str = "/acch/seed";
/// Topic of the camera calibration (one per frame).
pub const TOPIC_CALIBRATION: &str = "/camera/calibration";
/// Topic of the image overlay: detection, ROI, projected axes.
pub const TOPIC_OVERLAY: &str = "/acch/overlay";
/// Topic of the mask overlay.
pub const TOPIC_MASK_OVERLAY: &str = "/acch/mask/overlay";
/// Topic of the pose transforms.
pub const TOPIC_TF: &str = "/tf";
/// Topic of the per-stage latencies.
pub const TOPIC_LATENCY: &str = "/acch/latency";
/// The camera's optical frame (OpenCV: x right, y down, z forward).
pub const CAMERA_FRAME: &str = "camera_optical";
/// The camera's body frame (ROS: x forward, y left, z up), parent of
/// [`CAMERA_FRAME`] on `/tf`: a 3-D viewer following it has z up.
pub const CAMERA_BODY_FRAME: &str = "camera";
/// camera_from_optical rotation x, y, z, w: optical z (forward) is body x,
/// optical x (right) body -y, optical y (down) body -z.
pub const BODY_FROM_OPTICAL_XYZW: [f64; 4] = [-0.5, 0.5, -0.5, 0.5];

/// The iceoryx2 control event the `record` process sends after writing each
/// final result; a free-running replay waits for it so a replay recorded
/// again loses no frame.
pub const RECORDED_EVENT: &str = "recorded";
/// The event id is the frame's sequence modulo this (iceoryx2 allows ids up
/// to 255), so notifications about different frames in flight do not merge.
pub const RECORDED_IDS: u64 = 128;

/// Why a recording could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The file could not be created, read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The MCAP library rejected the file (truncated, bad CRC, bad record).
    #[error("{path}: not a valid MCAP recording: {source}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// What the MCAP reader or writer reported.
        source: McapError,
    },
    /// A message could not be decoded.
    #[error("cannot decode {what}: {reason}")]
    Decode {
        /// Message type.
        what: String,
        /// What was wrong.
        reason: String,
    },
    /// The recording is readable but not a usable acch recording.
    #[error("{path}: {reason}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What was wrong.
        reason: String,
    },
}

/// Channel ids of a recording.
struct Channels {
    image: u16,
    frame: u16,
    mask: u16,
    response: u16,
    result: u16,
    seed: u16,
    calibration: u16,
    overlay: u16,
    mask_overlay: u16,
    tf: u16,
    latency: u16,
}

/// What the image overlay of a result shows (pixels, image coordinates).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overlay {
    /// Detection window x, y, width, height.
    pub window: Option<[f64; 4]>,
    /// Segmented region's box x, y, width, height.
    pub roi: Option<[f64; 4]>,
    /// The seed's origin and x, y, z axis tips, projected.
    pub seed_axes: Option<[[f64; 2]; 4]>,
    /// The true pose's, likewise.
    pub truth_axes: Option<[[f64; 2]; 4]>,
    /// A line of text at the top left (estimate, rating).
    pub caption: String,
}

/// Writes one run into an MCAP file. Every `write_*` call reuses one
/// scratch buffer, so after the first frames the recorder stops allocating.
pub struct Recorder<W: Write + Seek = BufWriter<File>> {
    out: mcap::Writer<W>,
    ch: Channels,
    scratch: Vec<u8>,
    path: PathBuf,
    epoch_offset_ns: u64,
    /// 1 at the first view of each θ slice (database order), else 0.
    slice_edges: Vec<u8>,
    /// Row runs of the current mask.
    runs: Vec<[f64; 2]>,
}

impl Recorder<BufWriter<File>> {
    /// Creates `path`. `epoch_offset_ns` is added to CLOCK_MONOTONIC capture
    /// times to get the Unix-epoch log times MCAP tools expect.
    pub fn create(path: &Path, epoch_offset_ns: u64) -> Result<Self, RecordError> {
        let file = File::create(path).map_err(|source| RecordError::Io {
            path: path.to_owned(),
            source,
        })?;
        // Large buffer: a frame is ~1 MB; fewer, larger writes.
        Self::new(
            BufWriter::with_capacity(1 << 20, file),
            path,
            epoch_offset_ns,
        )
    }
}

impl<W: Write + Seek> Recorder<W> {
    /// A recorder writing to `w`; `path` names it in errors.
    pub fn new(w: W, path: &Path, epoch_offset_ns: u64) -> Result<Self, RecordError> {
        let e = |source| RecordError::Mcap {
            path: path.to_owned(),
            source,
        };
        let mut out = WriteOptions::new()
            .profile("")
            .library(concat!("acch-record ", env!("CARGO_PKG_VERSION")))
            .compression(None)
            .create(w)
            .map_err(e)?;
        let raw = out
            .add_schema(
                "foxglove.RawImage",
                "protobuf",
                &proto::raw_image_descriptor_set(),
            )
            .map_err(e)?;
        let pose = out
            .add_schema(
                "foxglove.PoseInFrame",
                "protobuf",
                &proto::pose_in_frame_descriptor_set(),
            )
            .map_err(e)?;
        let annotations = out
            .add_schema(
                "foxglove.ImageAnnotations",
                "protobuf",
                &proto::image_annotations_descriptor_set(),
            )
            .map_err(e)?;
        let transforms = out
            .add_schema(
                "foxglove.FrameTransforms",
                "protobuf",
                &proto::frame_transforms_descriptor_set(),
            )
            .map_err(e)?;
        let calibration = out
            .add_schema(
                "foxglove.CameraCalibration",
                "protobuf",
                &proto::camera_calibration_descriptor_set(),
            )
            .map_err(e)?;
        let json = |out: &mut mcap::Writer<W>, name: &str, schema: &str| {
            out.add_schema(name, "jsonschema", schema.as_bytes())
        };
        let frame_s = json(&mut out, "acch.Frame", schema::FRAME_SCHEMA).map_err(e)?;
        let response_s = json(&mut out, "acch.Response", schema::RESPONSE_SCHEMA).map_err(e)?;
        let result_s = json(&mut out, "acch.Result", schema::RESULT_SCHEMA).map_err(e)?;
        let latency_s = json(&mut out, "acch.Latency", schema::LATENCY_SCHEMA).map_err(e)?;
        let none = BTreeMap::new();
        let mask_meta = BTreeMap::from([(
            "values".to_owned(),
            "0 background, non-zero (255) object".to_owned(),
        )]);
        let ch = Channels {
            image: out
                .add_channel(raw, TOPIC_IMAGE, "protobuf", &none)
                .map_err(e)?,
            frame: out
                .add_channel(frame_s, TOPIC_FRAME, "json", &none)
                .map_err(e)?,
            mask: out
                .add_channel(raw, TOPIC_MASK, "protobuf", &mask_meta)
                .map_err(e)?,
            response: out
                .add_channel(response_s, TOPIC_RESPONSE, "json", &none)
                .map_err(e)?,
            result: out
                .add_channel(result_s, TOPIC_RESULT, "json", &none)
                .map_err(e)?,
            seed: out
                .add_channel(pose, TOPIC_SEED, "protobuf", &none)
                .map_err(e)?,
            calibration: out
                .add_channel(calibration, TOPIC_CALIBRATION, "protobuf", &none)
                .map_err(e)?,
            overlay: out
                .add_channel(annotations, TOPIC_OVERLAY, "protobuf", &none)
                .map_err(e)?,
            mask_overlay: out
                .add_channel(annotations, TOPIC_MASK_OVERLAY, "protobuf", &none)
                .map_err(e)?,
            tf: out
                .add_channel(transforms, TOPIC_TF, "protobuf", &none)
                .map_err(e)?,
            latency: out
                .add_channel(latency_s, TOPIC_LATENCY, "json", &none)
                .map_err(e)?,
        };
        Ok(Recorder {
            out,
            ch,
            scratch: Vec::new(),
            path: path.to_owned(),
            epoch_offset_ns,
            slice_edges: Vec::new(),
            runs: Vec::new(),
        })
    }

    /// Tells the recorder the θ of every database view (database order):
    /// each response then carries `slice_edges`, which a plot over the
    /// view index draws as a spike at the start of each θ slice.
    pub fn set_view_thetas(&mut self, thetas: &[f32]) {
        self.slice_edges = thetas
            .iter()
            .enumerate()
            .map(|(i, t)| u8::from(i == 0 || thetas[i - 1] != *t))
            .collect();
    }

    fn put(&mut self, channel: u16, sequence: u64, capture_ns: u64) -> Result<(), RecordError> {
        let t = capture_ns.saturating_add(self.epoch_offset_ns);
        let header = MessageHeader {
            channel_id: channel,
            // MCAP sequences are 32-bit: a run at 30 fps wraps after 4.5 years.
            sequence: sequence as u32,
            log_time: t,
            publish_time: t,
        };
        self.out
            .write_to_known_channel(&header, &self.scratch)
            .map_err(|source| RecordError::Mcap {
                path: self.path.clone(),
                source,
            })
    }

    fn put_json(
        &mut self,
        channel: u16,
        sequence: u64,
        capture_ns: u64,
        v: &impl Serialize,
    ) -> Result<(), RecordError> {
        self.scratch.clear();
        serde_json::to_writer(&mut self.scratch, v).map_err(|e| RecordError::Decode {
            what: "JSON message".into(),
            reason: e.to_string(),
        })?;
        self.put(channel, sequence, capture_ns)
    }

    /// Records a frame: its metadata on `/acch/frame`, then its pixels
    /// (packed rgb8, `width * 3` bytes a row) on `/camera/image`.
    pub fn frame(&mut self, info: &FrameInfo, rgb: &[u8]) -> Result<(), RecordError> {
        let expected = info.width as usize * info.height as usize * 3;
        if rgb.len() != expected {
            return Err(RecordError::Invalid {
                path: self.path.clone(),
                reason: format!(
                    "frame {} has {} bytes, {}x{} rgb8 needs {expected}",
                    info.sequence,
                    rgb.len(),
                    info.width,
                    info.height
                ),
            });
        }
        self.put_json(self.ch.frame, info.sequence, info.capture_ns, info)?;
        let h = RawImageHeader {
            stamp_ns: info.capture_ns.saturating_add(self.epoch_offset_ns),
            frame_id: CAMERA_FRAME.into(),
            width: info.width,
            height: info.height,
            encoding: "rgb8".into(),
            step: info.width * 3,
        };
        proto::encode_raw_image(&mut self.scratch, &h, rgb);
        self.put(self.ch.image, info.sequence, info.capture_ns)?;
        // Every frame: a viewer that seeks finds one close by.
        proto::encode_camera_calibration(
            &mut self.scratch,
            &proto::Calibration {
                stamp_ns: h.stamp_ns,
                frame_id: CAMERA_FRAME.into(),
                width: info.width,
                height: info.height,
                intrinsics: info.intrinsics,
                distortion: info
                    .distortion
                    .as_ref()
                    .map(|(m, k)| (m.clone(), distortion_coefficients(m, k))),
            },
        );
        self.put(self.ch.calibration, info.sequence, info.capture_ns)
    }

    /// Records a segmentation mask (`width * height` bytes, 0 = background,
    /// non-zero = object) as mono8, and its overlay.
    pub fn mask(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        width: u32,
        height: u32,
        mask: &[u8],
    ) -> Result<(), RecordError> {
        let h = RawImageHeader {
            stamp_ns: capture_ns.saturating_add(self.epoch_offset_ns),
            frame_id: CAMERA_FRAME.into(),
            width,
            height,
            encoding: "mono8".into(),
            step: width,
        };
        proto::encode_raw_image(&mut self.scratch, &h, mask);
        self.put(self.ch.mask, sequence, capture_ns)?;
        proto::mask_runs(mask, width, &mut self.runs);
        let fill = [PointsAnnotation {
            kind: PointsKind::LineList,
            points: std::mem::take(&mut self.runs),
            color: [0.0, 1.0, 0.3, 0.4],
            colors: Vec::new(),
            fill: None,
            thickness: 1.0,
        }];
        proto::encode_image_annotations(&mut self.scratch, h.stamp_ns, &fill, &[]);
        // The points' buffer is reused by the next mask.
        let [fill] = fill;
        self.runs = fill.points;
        self.put(self.ch.mask_overlay, sequence, capture_ns)
    }

    /// Records the pose stage's match values (one per database view).
    pub fn response(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        values: &[f32],
    ) -> Result<(), RecordError> {
        self.put_json(
            self.ch.response,
            sequence,
            capture_ns,
            &ResponseJson {
                sequence,
                values: values.to_vec(),
                slice_edges: if self.slice_edges.len() == values.len() {
                    self.slice_edges.clone()
                } else {
                    Vec::new()
                },
            },
        )
    }

    /// Records a final result (any serialisable JSON view of it).
    pub fn result(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        result: &impl Serialize,
    ) -> Result<(), RecordError> {
        self.put_json(self.ch.result, sequence, capture_ns, result)
    }

    /// Records a seed: camera_from_object translation and rotation (x, y,
    /// z, w) in the camera's optical frame.
    pub fn seed(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        translation: [f64; 3],
        rotation_xyzw: [f64; 4],
    ) -> Result<(), RecordError> {
        proto::encode_pose_in_frame(
            &mut self.scratch,
            capture_ns.saturating_add(self.epoch_offset_ns),
            CAMERA_FRAME,
            translation,
            rotation_xyzw,
        );
        self.put(self.ch.seed, sequence, capture_ns)
    }

    /// Records the image overlay of a result on `/acch/overlay`: the
    /// detection window (yellow), the ROI (cyan), the seed's axes (x red,
    /// y green, z blue), the true axes (faint) and a caption.
    pub fn overlay(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        o: &Overlay,
    ) -> Result<(), RecordError> {
        let rect = |[x, y, w, h]: [f64; 4], color: proto::Rgba| PointsAnnotation {
            kind: PointsKind::LineLoop,
            points: vec![[x, y], [x + w, y], [x + w, y + h], [x, y + h]],
            color,
            colors: Vec::new(),
            fill: None,
            thickness: 2.0,
        };
        let axes = |px: [[f64; 2]; 4], alpha: f64, thickness: f64| PointsAnnotation {
            kind: PointsKind::LineList,
            points: vec![px[0], px[1], px[0], px[2], px[0], px[3]],
            color: [1.0, 1.0, 1.0, alpha],
            // One colour per point: both ends of a segment alike.
            colors: [
                [1.0, 0.15, 0.15, alpha],
                [0.15, 0.9, 0.15, alpha],
                [0.25, 0.45, 1.0, alpha],
            ]
            .into_iter()
            .flat_map(|c| [c, c])
            .collect(),
            fill: None,
            thickness,
        };
        let mut points = Vec::new();
        let mut texts = Vec::new();
        let label = |at: [f64; 2], text: &str, color: proto::Rgba| TextAnnotation {
            position: at,
            text: text.into(),
            font_size: 13.0,
            color,
            background: [0.0, 0.0, 0.0, 0.6],
        };
        const YELLOW: proto::Rgba = [1.0, 0.86, 0.0, 1.0];
        const CYAN: proto::Rgba = [0.0, 0.8, 1.0, 1.0];
        if let Some(w) = o.window {
            points.push(rect(w, YELLOW));
            texts.push(label([w[0], w[1] - 4.0], "detection", YELLOW));
        }
        if let Some(r) = o.roi {
            points.push(rect(r, CYAN));
            texts.push(label([r[0], r[1] + r[3] + 14.0], "roi", CYAN));
        }
        if let Some(px) = o.truth_axes {
            points.push(axes(px, 0.55, 1.5));
        }
        if let Some(px) = o.seed_axes {
            points.push(axes(px, 1.0, 3.0));
            texts.push(label(px[0], "seed", [1.0, 0.63, 0.0, 1.0]));
        }
        if !o.caption.is_empty() {
            texts.push(label([8.0, 20.0], &o.caption, [1.0; 4]));
        }
        let stamp = capture_ns.saturating_add(self.epoch_offset_ns);
        proto::encode_image_annotations(&mut self.scratch, stamp, &points, &texts);
        self.put(self.ch.overlay, sequence, capture_ns)
    }

    /// Records poses as frames of `camera_optical` on `/tf` (`child`,
    /// camera_from_child translation and rotation x, y, z, w), after the
    /// fixed `camera` -> `camera_optical` transform.
    pub fn transforms(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        poses: &[(&str, [f64; 3], [f64; 4])],
    ) -> Result<(), RecordError> {
        let body = FrameTransform {
            parent: CAMERA_BODY_FRAME.into(),
            child: CAMERA_FRAME.into(),
            translation: [0.0; 3],
            rotation_xyzw: BODY_FROM_OPTICAL_XYZW,
        };
        let transforms: Vec<FrameTransform> = std::iter::once(body)
            .chain(poses.iter().map(|(child, t, q)| FrameTransform {
                parent: CAMERA_FRAME.into(),
                child: (*child).into(),
                translation: *t,
                rotation_xyzw: *q,
            }))
            .collect();
        let stamp = capture_ns.saturating_add(self.epoch_offset_ns);
        proto::encode_frame_transforms(&mut self.scratch, stamp, &transforms);
        self.put(self.ch.tf, sequence, capture_ns)
    }

    /// Records a frame's latencies on `/acch/latency`.
    pub fn latency(
        &mut self,
        sequence: u64,
        capture_ns: u64,
        latency: &LatencyJson,
    ) -> Result<(), RecordError> {
        self.put_json(self.ch.latency, sequence, capture_ns, latency)
    }

    /// Adds a metadata record (e.g. the recorder's counts at the end).
    pub fn metadata(
        &mut self,
        name: &str,
        entries: BTreeMap<String, String>,
    ) -> Result<(), RecordError> {
        self.out
            .write_metadata(&mcap::records::Metadata {
                name: name.to_owned(),
                metadata: entries,
            })
            .map_err(|source| RecordError::Mcap {
                path: self.path.clone(),
                source,
            })
    }

    /// Writes the summary and footer and flushes; the file is complete.
    pub fn finish(mut self) -> Result<(), RecordError> {
        let e = |source| RecordError::Mcap {
            path: self.path.clone(),
            source,
        };
        self.out.finish().map_err(e)?;
        let path = self.path.clone();
        self.out
            .into_inner()
            .flush()
            .map_err(|source| RecordError::Io { path, source })
    }
}

/// The coefficients a `CameraCalibration` of `model` carries: ROS
/// `plumb_bob` has k1 k2 p1 p2 k3, `rational_polynomial` all eight.
fn distortion_coefficients(model: &str, k: &[f64; 8]) -> Vec<f64> {
    if model == "plumb_bob" {
        k[..5].to_vec()
    } else {
        k.to_vec()
    }
}

/// One recorded frame, read back: its metadata and its pixels.
pub struct ReplayFrame {
    /// Sequence, capture time, size, intrinsics, truth.
    pub info: FrameInfo,
    message: Vec<u8>,
    pixels: std::ops::Range<usize>,
}

impl ReplayFrame {
    /// Packed rgb8 pixels, `info.width * 3` bytes a row.
    pub fn pixels(&self) -> &[u8] {
        &self.message[self.pixels.clone()]
    }
}

/// Reads the frames of a recording in order, CRCs checked, streaming (memory
/// stays at about one chunk however long the recording).
pub struct ReplayReader {
    messages: mcap::io::MessageReader<BufReader<File>>,
    path: PathBuf,
    info: Option<FrameInfo>,
}

fn reader_options() -> LinearReaderOptions {
    LinearReaderOptions::default()
        .with_validate_chunk_crcs(true)
        .with_validate_data_section_crc(true)
        .with_validate_summary_section_crc(true)
}

impl ReplayReader {
    /// Opens `path`.
    pub fn open(path: &Path) -> Result<Self, RecordError> {
        let file = File::open(path).map_err(|source| RecordError::Io {
            path: path.to_owned(),
            source,
        })?;
        Ok(ReplayReader {
            messages: mcap::io::MessageReader::new_with_options(
                BufReader::with_capacity(1 << 20, file),
                reader_options(),
            ),
            path: path.to_owned(),
            info: None,
        })
    }

    fn invalid(&self, reason: String) -> RecordError {
        RecordError::Invalid {
            path: self.path.clone(),
            reason,
        }
    }

    fn next_frame(&mut self) -> Result<Option<ReplayFrame>, RecordError> {
        while let Some(m) = self.messages.next() {
            let m = m.map_err(|source| RecordError::Mcap {
                path: self.path.clone(),
                source,
            })?;
            match m.channel.topic.as_str() {
                TOPIC_FRAME => {
                    let info: FrameInfo = serde_json::from_slice(&m.data).map_err(|e| {
                        self.invalid(format!("{TOPIC_FRAME} message {}: {e}", m.sequence))
                    })?;
                    self.info = Some(info);
                }
                TOPIC_IMAGE => {
                    let data = m.data.into_owned();
                    let (h, px) = proto::decode_raw_image(&data)
                        .map_err(|e| self.invalid(format!("{TOPIC_IMAGE} {}: {e}", m.sequence)))?;
                    let info = match self.info.take() {
                        Some(i) if i.sequence as u32 == m.sequence => i,
                        _ => {
                            return Err(self.invalid(format!(
                                "image {} has no {TOPIC_FRAME} message before it",
                                m.sequence
                            )));
                        }
                    };
                    if h.encoding != "rgb8"
                        || h.width != info.width
                        || h.height != info.height
                        || h.step != info.width * 3
                        || px.len() != info.width as usize * info.height as usize * 3
                    {
                        return Err(self.invalid(format!(
                            "frame {}: image is {}x{} {} (step {}, {} bytes), metadata says {}x{} rgb8",
                            info.sequence,
                            h.width,
                            h.height,
                            h.encoding,
                            h.step,
                            px.len(),
                            info.width,
                            info.height
                        )));
                    }
                    let start = px.as_ptr() as usize - data.as_ptr() as usize;
                    let pixels = start..start + px.len();
                    return Ok(Some(ReplayFrame {
                        info,
                        message: data,
                        pixels,
                    }));
                }
                _ => {}
            }
        }
        Ok(None)
    }
}

impl Iterator for ReplayReader {
    type Item = Result<ReplayFrame, RecordError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_frame().transpose()
    }
}

/// What a recording holds (read once through, every CRC checked).
#[derive(Clone, Debug, PartialEq)]
pub struct RecordingSummary {
    /// Frames.
    pub frames: u64,
    /// Size of the first frame.
    pub width: u32,
    /// Size of the first frame.
    pub height: u32,
}

/// Reads the whole recording once: counts its frames and fails on a
/// truncated or corrupt file (before a replay starts, not halfway).
pub fn scan(path: &Path) -> Result<RecordingSummary, RecordError> {
    let mut s = RecordingSummary {
        frames: 0,
        width: 0,
        height: 0,
    };
    for f in ReplayReader::open(path)? {
        let f = f?;
        if s.frames == 0 {
            (s.width, s.height) = (f.info.width, f.info.height);
        }
        s.frames += 1;
    }
    if s.frames == 0 {
        return Err(RecordError::Invalid {
            path: path.to_owned(),
            reason: format!("holds no frames on {TOPIC_IMAGE}"),
        });
    }
    Ok(s)
}

/// Size of the first frame of a recording (reads only up to it).
pub fn first_frame_size(path: &Path) -> Result<(u32, u32), RecordError> {
    match ReplayReader::open(path)?.next() {
        Some(f) => {
            let f = f?;
            Ok((f.info.width, f.info.height))
        }
        None => Err(RecordError::Invalid {
            path: path.to_owned(),
            reason: format!("holds no frames on {TOPIC_IMAGE}"),
        }),
    }
}

/// Every message on `topic` as JSON, in file order (for tests and tools).
pub fn read_json(path: &Path, topic: &str) -> Result<Vec<serde_json::Value>, RecordError> {
    let file = File::open(path).map_err(|source| RecordError::Io {
        path: path.to_owned(),
        source,
    })?;
    let mut out = Vec::new();
    for m in mcap::io::MessageReader::new_with_options(BufReader::new(file), reader_options()) {
        let m = m.map_err(|source| RecordError::Mcap {
            path: path.to_owned(),
            source,
        })?;
        if m.channel.topic == topic {
            out.push(
                serde_json::from_slice(&m.data).map_err(|e| RecordError::Invalid {
                    path: path.to_owned(),
                    reason: format!("{topic} message {}: {e}", m.sequence),
                })?,
            );
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests;
