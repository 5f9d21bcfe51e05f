//! The `record` process: every frame and result of a run into MCAP
//! (`acch run --record FILE.mcap`). Off the hot path: it subscribes to the
//! frame service and to the segmentation (mask), pose (response) and seeding
//! (final result) services like any stage, but nothing waits for it. When
//! it falls behind, iceoryx2 drops the oldest samples queued for it; the
//! gaps in sequence numbers are counted and reported.

use crate::stages::{PipelineConfig, ResultJson};
use acch_ipc::{Observer, ResultMsg, StageId};
use acch_record::{FrameInfo, FrameTruth, Recorder};
use anyhow::{Context, Result, anyhow};
use iceoryx2::prelude::EventId;
use serde::Serialize;
use std::collections::BTreeMap;
use std::time::Duration;

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
    let frames = ipc.frame_input(false)?;
    let masks = ipc.result_input(StageId::Segmentation)?;
    let responses = ipc.result_input(StageId::Pose)?;
    let results = ipc.result_input(StageId::Seeding)?;
    let recorded = ipc.control_notifier(acch_record::RECORDED_EVENT)?;
    // The frame-sized mask of each result, rebuilt from its crop.
    let mut mask = Vec::new();
    let mut rec = Recorder::create(&path, epoch_offset_ns())?;
    announce_ready(&ipc, Observer::Record)?;
    let mut s = RecordSummary {
        file: path.display().to_string(),
        ..Default::default()
    };
    let mut gaps = [Gaps::default(); 4];
    let object = cfg.object.as_str();
    // Wakes on final results (the last event of a frame); the timeout keeps
    // frames flowing if results stop and lets SIGINT through.
    let mut running = true;
    while running {
        running = ipc.keep_running();
        results.wait(Duration::from_millis(50))?;
        // After SIGINT this is the final drain: everything published before
        // the launcher stopped us is still queued for us.
        while let Some(f) = frames.receive()? {
            let h = f.user_header();
            gaps[0].see(h.sequence);
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
            if f.payload().is_empty() {
                // The copy transport sends pixels through sockets, not here.
                continue;
            }
            rec.frame(&info, f.payload())?;
            s.frames += 1;
        }
        while let Some(m) = masks.receive()? {
            let h = m.user_header();
            gaps[1].see(h.sequence);
            if h.segmented == 1 && frame_mask(h, m.payload(), &mut mask) {
                let (w, hh) = (h.width as u32, h.height as u32);
                rec.mask(h.sequence, h.trail.captured_ns, w, hh, &mask)?;
                s.masks += 1;
            }
        }
        while let Some(r) = responses.receive()? {
            let h = r.user_header();
            gaps[2].see(h.sequence);
            if h.estimated == 1 {
                let values = f32s(r.payload());
                rec.response(h.sequence, h.trail.captured_ns, &values)?;
                s.responses += 1;
            }
        }
        while let Some(r) = results.receive()? {
            let m = r.user_header();
            gaps[3].see(m.sequence);
            let t = m.trail.captured_ns;
            rec.result(m.sequence, t, &ResultJson::of(object, m))?;
            s.results += 1;
            if m.seeded == 1 && m.accepted == 1 {
                rec.seed(m.sequence, t, m.seed_translation, m.seed_rotation_xyzw)?;
                s.seeds += 1;
            }
            // A free-running replay paces itself on this (see capture).
            let id = (m.sequence % acch_record::RECORDED_IDS) as usize;
            recorded
                .notify_with_custom_event_id(EventId::new(id))
                .map_err(|e| anyhow!("record: notifying {}: {e:?}", acch_record::RECORDED_EVENT))?;
        }
    }
    [
        s.frames_missed,
        s.masks_missed,
        s.responses_missed,
        s.results_missed,
    ] = gaps.map(|g| g.missed);
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

/// The frame-sized mask of segmentation's result `h` into `out`: the
/// payload starts with the mask cropped to `h.roi` (the colour indices for
/// pose follow). False, leaving `out` empty, when the ROI does not fit the
/// frame or the payload.
pub(crate) fn frame_mask(h: &ResultMsg, payload: &[u8], out: &mut Vec<u8>) -> bool {
    out.clear();
    let (w, fh) = (h.width as usize, h.height as usize);
    let [x, y, rw, rh] = h.roi.map(|v| v as usize);
    if x + rw > w || y + rh > fh || rw * rh > payload.len() {
        return false;
    }
    out.resize(w * fh, 0);
    if rw > 0 {
        for (row, src) in payload[..rw * rh].chunks_exact(rw).enumerate() {
            let at = (y + row) * w + x;
            out[at..at + rw].copy_from_slice(src);
        }
    }
    true
}

/// The pose stage's response payload: native-endian f32s.
fn f32s(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_ne_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Counts sequence numbers missing from a stream that should see every
/// frame (each stream starts at frame 0).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Gaps {
    next: u64,
    /// Sequence numbers skipped so far.
    pub missed: u64,
}

impl Gaps {
    /// Notes that `sequence` arrived.
    pub(crate) fn see(&mut self, sequence: u64) {
        self.missed += sequence.saturating_sub(self.next);
        self.next = self.next.max(sequence + 1);
    }
}

/// Niceness of the observer processes: when a stage and an observer are
/// both runnable, the scheduler runs the stage (the observers still get
/// the cores' idle time, which is most of it).
pub(crate) const OBSERVER_NICE: libc::c_int = 10;

/// Lowers this process's priority to the normal scheduler at
/// [`OBSERVER_NICE`]; call before any
/// thread starts (threads inherit it).
pub(crate) fn lower_priority(o: Observer) {
    // Under `realtime_priority` the launcher's SCHED_FIFO is inherited:
    // observers leave it, so they never preempt a stage.
    if let Err(e) = acch_ipc::sched::set_normal() {
        tracing::warn!("{}: could not leave the real-time scheduler: {e}", o.name());
    }
    // SAFETY: setpriority(2) on this process, no pointers.
    let r = unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, OBSERVER_NICE) };
    if r != 0 {
        tracing::warn!(
            "{}: could not lower priority: {}",
            o.name(),
            std::io::Error::last_os_error()
        );
    }
}

/// Tells the launcher this observer is connected (it starts the capture
/// only when every stage and observer is).
pub(crate) fn announce_ready(ipc: &acch_ipc::Ipc, o: Observer) -> Result<()> {
    ipc.control_notifier("ready")?
        .notify_with_custom_event_id(EventId::new(o.ready_id()))
        .map_err(|e| anyhow!("{} announcing readiness: {e:?}", o.name()))?;
    Ok(())
}

/// Unix-epoch time minus CLOCK_MONOTONIC, ns: maps capture times to the
/// wall-clock times MCAP tools expect.
pub(crate) fn epoch_offset_ns() -> u64 {
    let wall = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    wall.saturating_sub(acch_ipc::now_ns())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaps_count_skipped_sequences_including_a_late_start() {
        let mut g = Gaps::default();
        for s in [0, 1, 2, 5, 6, 9] {
            g.see(s);
        }
        assert_eq!(g.missed, 4);
        let mut g = Gaps::default();
        g.see(3);
        assert_eq!(g.missed, 3);
        // A repeat or an older sequence is not a gap.
        g.see(3);
        g.see(1);
        assert_eq!(g.missed, 3);
    }

    #[test]
    fn responses_decode_native_endian() {
        let v = [0.25f32, -1.5, f32::MAX];
        let b: Vec<u8> = v.iter().flat_map(|x| x.to_ne_bytes()).collect();
        assert_eq!(f32s(&b), v);
    }
}
