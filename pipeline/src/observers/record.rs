//! The recorder: every frame, region, response, result and seed of a run
//! into MCAP (`acch run --record FILE.mcap`), as Foxglove protobuf and JSON
//! messages ([`acch_record`]), with what a Foxglove layout shows beside
//! them (image overlays, pose transforms, latencies), or (`--record-format ros2`) a rosbag2 bag of
//! the run's ROS 2 topics ([`crate::ros2::Ros2Bag`]) that `ros2 bag play`
//! replays.

use super::viz::pose_of;
use crate::PipelineConfig;
use crate::frame::FrameHeader;
use crate::json::ResultJson;
use crate::node::{NodeError, announce_ready};
use crate::observe::{Observe, ObserveError, Observer, Streams, lower_priority};
use crate::stages::{Posed, RegionPayload, ResponsePayload, Seeded, Segmented};
use crate::wire::{Hop, StageId};
use acch_ipc::Control;
use acch_record::{FrameInfo, FrameTruth, LatencyJson, Overlay, Recorder};
use acch_viz::{ObjectSize, Pose, project_axes};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// What the recorder wrote and what it missed.
#[derive(Serialize, Debug, Default)]
pub struct RecordSummary {
    /// The MCAP file.
    pub file: String,
    /// Frames written.
    pub frames: u64,
    /// Masks written.
    pub masks: u64,
    /// Responses written.
    pub responses: u64,
    /// Final results written.
    pub results: u64,
    /// Seeds written.
    pub seeds: u64,
    /// Frames missing from the sequence (dropped while the recorder lagged,
    /// or never captured).
    pub frames_missed: u64,
    /// Masks missing from the sequence.
    pub masks_missed: u64,
    /// Responses missing from the sequence.
    pub responses_missed: u64,
    /// Results missing from the sequence (dropped here, or by a stage).
    pub results_missed: u64,
}

/// Writes what it observes into an MCAP file.
pub struct Recording {
    rec: Recorder,
    s: RecordSummary,
    object: String,
    views: usize,
    /// The frame-sized mask of the current region, pasted from its crop.
    mask: Vec<u8>,
    response: Vec<f32>,
    /// How long the projected axes are drawn.
    size: ObjectSize,
}

impl Recording {
    /// Creates `path` for a run of `object` over a database of `views` views.
    pub fn create(path: &Path, object: &str, views: usize) -> Result<Self, ObserveError> {
        Ok(Recording {
            rec: Recorder::create(path, epoch_offset_ns())?,
            s: RecordSummary {
                file: path.display().to_string(),
                ..Default::default()
            },
            object: object.to_owned(),
            views,
            mask: Vec::new(),
            response: Vec::with_capacity(views),
            size: ObjectSize::FromDistance,
        })
    }

    /// Tells the recording the θ of every database view (database order;
    /// the responses then mark the θ slices) and the object's size (the
    /// length of the axes drawn on the image).
    pub fn describe(&mut self, view_thetas: &[f32], size: ObjectSize) {
        self.rec.set_view_thetas(view_thetas);
        self.size = size;
    }

    /// Completes the file (its counts as metadata, summary, footer) and
    /// returns the counts, with `missed` (frames, masks, responses,
    /// results) from the streams.
    pub fn finish(self, missed: [u64; 4]) -> Result<RecordSummary, ObserveError> {
        let Recording { mut rec, mut s, .. } = self;
        [
            s.frames_missed,
            s.masks_missed,
            s.responses_missed,
            s.results_missed,
        ] = missed;
        let json = serde_json::to_value(&s)?;
        let meta: BTreeMap<String, String> = json
            .as_object()
            .into_iter()
            .flatten()
            .map(|(k, v)| (k.clone(), v.to_string()))
            .collect();
        rec.metadata("acch.record", meta)?;
        rec.finish()?;
        Ok(s)
    }
}

impl Observe for Recording {
    fn frame(&mut self, h: &FrameHeader, pixels: &[u8]) -> Result<(), ObserveError> {
        if pixels.is_empty() {
            return Ok(());
        }
        let f = &h.envelope.frame;
        let info = FrameInfo {
            sequence: f.sequence,
            capture_ns: h.envelope.trail.captured_ns,
            width: f.width,
            height: f.height,
            intrinsics: f.intrinsics.to_array(),
            truth: f.truth.get().map(|t| FrameTruth {
                theta_deg: t.theta_deg,
                phi_deg: t.phi_deg,
                distance_m: t.distance_m,
                roll_deg: t.roll_deg,
                camera_from_object: t.camera_from_object,
            }),
            arm_world_from_camera: f.arm.get().map(|a| a.world_from_camera),
            distortion: Some(f.intrinsics.lens())
                .filter(|l| !l.is_none())
                .map(|l| (l.model.name().to_owned(), l.coefficients)),
        };
        self.rec.frame(&info, pixels)?;
        self.s.frames += 1;
        Ok(())
    }

    fn region(&mut self, h: &Segmented, payload: &[u8]) -> Result<(), ObserveError> {
        if let Ok(Some(region)) = RegionPayload::read(h, payload) {
            let e = h.envelope();
            let (w, hh) = (e.frame.width, e.frame.height);
            region.frame_mask(w, hh, &mut self.mask);
            self.rec
                .mask(e.frame.sequence, e.trail.captured_ns, w, hh, &self.mask)?;
            self.s.masks += 1;
        }
        Ok(())
    }

    fn response(&mut self, h: &Posed, payload: &[u8]) -> Result<(), ObserveError> {
        if let Ok(Some(r)) = ResponsePayload::read(h, self.views, payload) {
            r.copy_into(&mut self.response);
            let e = h.envelope();
            self.rec
                .response(e.frame.sequence, e.trail.captured_ns, &self.response)?;
            self.s.responses += 1;
        }
        Ok(())
    }

    fn result(&mut self, m: &Seeded) -> Result<(), ObserveError> {
        let e = m.envelope();
        let (seq, t) = (e.frame.sequence, e.trail.captured_ns);
        self.rec.result(seq, t, &ResultJson::of(&self.object, m))?;
        self.s.results += 1;
        let seed = m.seed().filter(|_| m.accepted()).map(|s| Pose {
            translation: s.translation,
            rotation_xyzw: s.rotation_xyzw,
        });
        if let Some(s) = &seed {
            self.rec.seed(seq, t, s.translation, s.rotation_xyzw)?;
            self.s.seeds += 1;
        }
        let truth = e.frame.truth.get().map(|t| pose_of(&t.camera_from_object));
        let fused = m
            .seeding
            .fused
            .get()
            .map(|f| pose_of(&f.camera_from_object));
        // For viewers: the result drawn on the image, the poses as frames.
        let k = e.frame.intrinsics.to_array();
        let axes = |p: &Option<Pose>| {
            p.as_ref()
                .and_then(|p| project_axes(k, p, self.size.radius(p)))
        };
        let rect = |r: [u32; 4]| r.map(f64::from);
        let caption = match (m.pose().done(), m.rating().verdict()) {
            (Some(p), Some(v)) => format!(
                "θ {:.1}° φ {:.1}°  confidence {:.3} {} {:.2}{}: {}",
                p.theta_deg,
                p.phi_deg,
                v.confidence,
                if v.confidence >= v.threshold {
                    "≥"
                } else {
                    "<"
                },
                v.threshold,
                if v.ambiguous() {
                    format!(", rival {:.3} > {:.3}", v.rival, v.max_rival)
                } else if v.broad() {
                    format!(
                        ", crest {:.0}° ≥ {:.0}° in φ",
                        v.phi_plateau_deg, v.phi_plateau_limit_deg
                    )
                } else if v.misplaced() {
                    format!(", a view beyond 20° holds it {:+.2} in place", v.map_rival)
                } else if v.faint() {
                    format!(
                        ", faint: detection {:.2}x, match {:.2}",
                        v.detection_margin, v.match_value
                    )
                } else {
                    String::new()
                },
                m.rating().state()
            ),
            (Some(p), None) => format!(
                "θ {:.1}° φ {:.1}°  {}",
                p.theta_deg,
                p.phi_deg,
                m.rating().state()
            ),
            (None, _) => "no estimate".into(),
        };
        // What a viewer needs to read the estimate: which databases made it.
        let caption = match e.imaging.smoothed_for() {
            Some(why) => format!("{caption} (smoothed: {})", why.name()),
            None => caption,
        };
        let overlay = Overlay {
            window: m.detection().done().map(|w| rect(w.window.to_array())),
            roi: m.region().done().map(|r| rect(r.to_array())),
            seed_axes: axes(&seed),
            truth_axes: axes(&truth),
            caption,
        };
        self.rec.overlay(seq, t, &overlay)?;
        let poses: Vec<(&str, [f64; 3], [f64; 4])> =
            [("seed", seed), ("fused", fused), ("truth", truth)]
                .into_iter()
                .filter_map(|(name, p)| p.map(|p| (name, p.translation, p.rotation_xyzw)))
                .collect();
        self.rec.transforms(seq, t, &poses)?;
        let ms = |ns: u64| ns as f64 / 1e6;
        let latency = LatencyJson {
            sequence: seq,
            since_capture_ms: StageId::ALL
                .iter()
                .map(|s| {
                    let published = e.trail.of(*s).published_ns;
                    (s.name().to_owned(), ms(published.saturating_sub(t)))
                })
                .collect(),
            stage_ms: StageId::ALL
                .iter()
                .map(|s| (s.name().to_owned(), ms(e.trail.process_ns(*s))))
                .collect(),
        };
        self.rec.latency(seq, t, &latency)?;
        Ok(())
    }
}

/// The recording of a run in its configured format (`record_format`).
pub struct RunRecording {
    format: Format,
    /// Tells a free-running replay a result is recorded (see capture).
    recorded: Option<Control>,
}

enum Format {
    Foxglove(Box<Recording>),
    Ros2(Box<crate::ros2::Ros2Bag>),
}

impl RunRecording {
    /// Creates `path` for `cfg`'s run over a database of `views` views: an
    /// MCAP file, or with `observers.record_format = "ros2"` a bag directory.
    pub fn create(cfg: &PipelineConfig, path: &Path, views: usize) -> Result<Self, ObserveError> {
        let format = if cfg.observers.record_format == crate::config::RecordFormat::Ros2 {
            let dir = crate::ros2::bag_dir(path);
            let bag = crate::ros2::Ros2Bag::create(&dir, &cfg.ros2, &cfg.object.name)?;
            tracing::info!("record: a rosbag2 bag in {}", dir.display());
            Format::Ros2(Box::new(bag))
        } else {
            let mut r = Recording::create(path, &cfg.object.name, views)?;
            // The views' θ mark the slices of each recorded response; the
            // database was read to start the run, so this read succeeds
            // unless the file changed since (then the marks are left out).
            match cfg.database() {
                Ok(db) => {
                    let thetas: Vec<f32> = db.views().iter().map(|v| v.theta_deg).collect();
                    r.describe(&thetas, object_size(cfg));
                }
                Err(e) => tracing::warn!("record: no θ slice marks in the responses: {e}"),
            }
            Format::Foxglove(Box::new(r))
        };
        Ok(RunRecording {
            format,
            recorded: None,
        })
    }

    /// Completes the recording and returns its counts, with `missed`
    /// (frames, masks, responses, results) from the streams.
    pub fn finish(self, missed: [u64; 4]) -> Result<RecordSummary, ObserveError> {
        match self.format {
            Format::Foxglove(r) => r.finish(missed),
            Format::Ros2(bag) => {
                let [frames, seeds, _, results] = bag.counts;
                let file = bag.mcap_path().display().to_string();
                bag.finish()?;
                Ok(RecordSummary {
                    file,
                    frames,
                    results,
                    seeds,
                    frames_missed: missed[0],
                    masks_missed: missed[1],
                    responses_missed: missed[2],
                    results_missed: missed[3],
                    ..Default::default()
                })
            }
        }
    }

    fn inner(&mut self) -> &mut dyn Observe {
        match &mut self.format {
            Format::Foxglove(r) => r.as_mut(),
            Format::Ros2(b) => b.as_mut(),
        }
    }
}

impl Observe for RunRecording {
    fn frame(&mut self, h: &FrameHeader, pixels: &[u8]) -> Result<(), ObserveError> {
        self.inner().frame(h, pixels)
    }

    fn region(&mut self, h: &Segmented, payload: &[u8]) -> Result<(), ObserveError> {
        self.inner().region(h, payload)
    }

    fn response(&mut self, h: &Posed, payload: &[u8]) -> Result<(), ObserveError> {
        self.inner().response(h, payload)
    }

    fn results_start(&mut self, gaps: &[crate::observe::Gaps; 4]) {
        self.inner().results_start(gaps);
    }

    fn results_end(&mut self, gaps: &[crate::observe::Gaps; 4]) -> Result<(), ObserveError> {
        self.inner().results_end(gaps)
    }

    fn result(&mut self, m: &Seeded) -> Result<(), ObserveError> {
        self.inner().result(m)?;
        if let Some(n) = &self.recorded {
            // A free-running replay paces itself on this (see capture).
            let seq = m.envelope().frame.sequence;
            n.notify((seq % acch_record::RECORDED_IDS) as usize)
                .map_err(acch_ipc::IpcError::from)?;
        }
        Ok(())
    }
}

/// Runs the recorder process until SIGINT, then drains what is queued,
/// completes the file and prints its counts.
pub fn run_record(cfg: &PipelineConfig) -> Result<RecordSummary, NodeError> {
    let path = cfg
        .observers
        .record
        .clone()
        .ok_or(crate::config::ConfigError::Invalid {
            key: "observers.record",
            value: String::new(),
            why: "the record process needs a file",
        })?;
    lower_priority(Observer::Record);
    let views = cfg.database()?.views().len();
    let ipc = cfg.ipc("record")?;
    let mut streams = Streams::open(&ipc, cfg.run.frame_history)?;
    let mut out = RunRecording::create(cfg, &path, views)?;
    out.recorded = Some(ipc.control_notifier(acch_record::RECORDED_EVENT)?);
    announce_ready(&ipc, Observer::Record.ready_id())?;
    streams.observe_until_stopped(&ipc, &mut out)?;
    let s = out.finish(streams.missed())?;
    if s.frames_missed + s.results_missed > 0 {
        tracing::warn!(
            "record: {} frames and {} results missing from {} (the recorder fell behind or stages dropped them)",
            s.frames_missed,
            s.results_missed,
            path.display()
        );
    }
    eprintln!(
        "acch record summary: {}",
        serde_json::to_string(&s).expect("counts serialise")
    );
    Ok(s)
}

/// The configured object's size: its real radius, or the built-in
/// object's (a mesh is loaded to measure it).
pub(crate) fn object_size(cfg: &PipelineConfig) -> ObjectSize {
    cfg.object
        .radius_m
        .or_else(|| cfg.scene_object().ok().map(|o| o.radius_m()))
        .map_or(ObjectSize::FromDistance, ObjectSize::RadiusM)
}

/// Unix-epoch time minus CLOCK_MONOTONIC, ns: maps capture times to the
/// wall-clock times MCAP tools expect.
pub fn epoch_offset_ns() -> u64 {
    acch_ipc::wall_ns().saturating_sub(acch_ipc::now_ns())
}
