//! The `record` process: every frame and result of a run into MCAP
//! (`acch run --record FILE.mcap`). Off the hot path: it subscribes to the
//! frame service and to the segmentation (mask), pose (response) and seeding
//! (final result) services like any stage, but nothing waits for it. When
//! it falls behind, iceoryx2 drops the oldest samples queued for it; the
//! gaps in sequence numbers are counted and reported.

use super::observe::{
    Observe, Streams, announce_ready, frame_mask, lower_priority, response_values,
};
use crate::stages::{PipelineConfig, ResultJson};
use acch_ipc::{FrameHeader, Observer, ResultMsg};
use acch_record::{FrameInfo, FrameTruth, Recorder};
use anyhow::{Context, Result, anyhow};
use iceoryx2::prelude::EventId;
use serde::Serialize;
use std::collections::BTreeMap;

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

/// Runs the recorder until SIGINT, then drains what is queued, completes
/// the file (summary, footer) and prints its counts.
pub fn run(cfg: &PipelineConfig) -> Result<()> {
    let path = cfg
        .record
        .clone()
        .ok_or_else(|| anyhow!("the configuration names no recording (record = FILE.mcap)"))?;
    lower_priority(Observer::Record);
    let ipc = cfg.ipc("record")?;
    let mut streams = Streams::open(&ipc)?;
    let recorded = ipc.control_notifier(acch_record::RECORDED_EVENT)?;
    let mut out = Recording {
        rec: Recorder::create(&path, epoch_offset_ns())?,
        s: RecordSummary {
            file: path.display().to_string(),
            ..Default::default()
        },
        mask: Vec::new(),
        object: cfg.object.as_str(),
        recorded,
    };
    announce_ready(&ipc, Observer::Record)?;
    streams.observe_until_stopped(&ipc, &mut out)?;
    let Recording { mut rec, mut s, .. } = out;
    [
        s.frames_missed,
        s.masks_missed,
        s.responses_missed,
        s.results_missed,
    ] = streams.missed();
    let json = serde_json::to_string(&s)?;
    let meta: BTreeMap<String, String> =
        serde_json::from_str::<BTreeMap<String, serde_json::Value>>(&json)?
            .into_iter()
            .map(|(k, v)| (k, v.to_string()))
            .collect();
    rec.metadata("acch.record", meta)?;
    rec.finish()
        .with_context(|| format!("completing {}", path.display()))?;
    if s.frames_missed + s.results_missed > 0 {
        tracing::warn!(
            "record: {} frames and {} results missing from {} (the recorder fell behind or stages dropped them)",
            s.frames_missed,
            s.results_missed,
            path.display()
        );
    }
    eprintln!("acch record summary: {json}");
    Ok(())
}

/// The recorder's side of each sample: written to the MCAP file.
struct Recording<'a> {
    rec: Recorder,
    s: RecordSummary,
    /// The frame-sized mask of the current result, rebuilt from its crop.
    mask: Vec<u8>,
    object: &'a str,
    /// Tells a free-running replay a result is recorded (see capture).
    recorded: iceoryx2::port::notifier::Notifier<acch_ipc::Svc>,
}

impl Observe for Recording<'_> {
    fn frame(&mut self, h: &FrameHeader, pixels: &[u8]) -> Result<()> {
        if pixels.is_empty() {
            return Ok(());
        }
        let info = FrameInfo {
            sequence: h.sequence,
            capture_ns: h.capture_ns,
            width: h.width as u32,
            height: h.height as u32,
            intrinsics: h.intrinsics,
            truth: (h.truth.valid == 1).then_some(FrameTruth {
                theta_deg: h.truth.theta_deg,
                phi_deg: h.truth.phi_deg,
                distance: h.truth.distance,
                camera_from_object: h.truth.camera_from_object,
            }),
        };
        self.rec.frame(&info, pixels)?;
        self.s.frames += 1;
        Ok(())
    }

    fn mask(&mut self, h: &ResultMsg, payload: &[u8]) -> Result<()> {
        if h.segmented == 1 && frame_mask(h, payload, &mut self.mask) {
            let (w, hh) = (h.width as u32, h.height as u32);
            self.rec
                .mask(h.sequence, h.trail.captured_ns, w, hh, &self.mask)?;
            self.s.masks += 1;
        }
        Ok(())
    }

    fn response(&mut self, h: &ResultMsg, payload: &[u8]) -> Result<()> {
        if h.estimated == 1 {
            let values = response_values(payload);
            self.rec
                .response(h.sequence, h.trail.captured_ns, &values)?;
            self.s.responses += 1;
        }
        Ok(())
    }

    fn result(&mut self, m: &ResultMsg) -> Result<()> {
        let t = m.trail.captured_ns;
        self.rec
            .result(m.sequence, t, &ResultJson::of(self.object, m))?;
        self.s.results += 1;
        if m.seeded == 1 && m.accepted == 1 {
            self.rec
                .seed(m.sequence, t, m.seed_translation, m.seed_rotation_xyzw)?;
            self.s.seeds += 1;
        }
        // A free-running replay paces itself on this (see capture).
        let id = (m.sequence % acch_record::RECORDED_IDS) as usize;
        self.recorded
            .notify_with_custom_event_id(EventId::new(id))
            .map_err(|e| anyhow!("record: notifying {}: {e:?}", acch_record::RECORDED_EVENT))?;
        Ok(())
    }
}

/// Unix-epoch time minus CLOCK_MONOTONIC, ns: maps capture times to the
/// wall-clock times MCAP tools expect.
pub(crate) fn epoch_offset_ns() -> u64 {
    let wall = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    wall.saturating_sub(acch_ipc::now_ns())
}
