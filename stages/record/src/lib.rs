//! Records acch frames and results to MCAP and reads them back for replay.
//!
//! Channels (every message's MCAP `sequence` is the frame number, its log
//! and publish time the capture time mapped to the Unix epoch):
//!
//! | topic | schema | encoding |
//! | --- | --- | --- |
//! | `/camera/image` | `foxglove.RawImage` (rgb8) | protobuf |
//! | `/acch/frame` | `acch.Frame`: sequence, capture time, intrinsics, truth | JSON |
//! | `/acch/mask` | `foxglove.RawImage` (mono8, 0 = background, 1 = object) | protobuf |
//! | `/acch/response` | `acch.Response`: match value per database view | JSON |
//! | `/acch/result` | `acch.Result`: the result published on zenoh | JSON |
//! | `/acch/seed` | `foxglove.PoseInFrame` (camera_from_object) | protobuf |
//!
//! Pixels are written once into the record (no base64, no compression): the
//! recorder runs beside the pipeline on the same cores and must stay cheap.

pub mod proto;
mod schema;

pub use schema::{FrameInfo, FrameTruth, ResponseJson};

use mcap::sans_io::LinearReaderOptions;
use mcap::{McapError, WriteOptions, records::MessageHeader};
use proto::RawImageHeader;
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
/// The camera's optical frame (OpenCV: x right, y down, z forward).
pub const CAMERA_FRAME: &str = "camera_optical";

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
}

/// Writes one run into an MCAP file. Every `write_*` call reuses one
/// scratch buffer, so after the first frames the recorder stops allocating.
pub struct Recorder<W: Write + Seek = BufWriter<File>> {
    out: mcap::Writer<W>,
    ch: Channels,
    scratch: Vec<u8>,
    path: PathBuf,
    epoch_offset_ns: u64,
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
        let json = |out: &mut mcap::Writer<W>, name: &str, schema: &str| {
            out.add_schema(name, "jsonschema", schema.as_bytes())
        };
        let frame_s = json(&mut out, "acch.Frame", schema::FRAME_SCHEMA).map_err(e)?;
        let response_s = json(&mut out, "acch.Response", schema::RESPONSE_SCHEMA).map_err(e)?;
        let result_s = json(&mut out, "acch.Result", schema::RESULT_SCHEMA).map_err(e)?;
        let none = BTreeMap::new();
        let mask_meta =
            BTreeMap::from([("values".to_owned(), "0 background, 1 object".to_owned())]);
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
        };
        Ok(Recorder {
            out,
            ch,
            scratch: Vec::new(),
            path: path.to_owned(),
            epoch_offset_ns,
        })
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
        self.put(self.ch.image, info.sequence, info.capture_ns)
    }

    /// Records a segmentation mask (`width * height` bytes, 0/1) as mono8.
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
        self.put(self.ch.mask, sequence, capture_ns)
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
