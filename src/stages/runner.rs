//! The generic stage process: wait, look the frame up, process, publish.

use super::{PipelineConfig, WAIT, copy};
use acch_ipc::{FrameHistory, Ipc, Output, ResultMsg, ShmLocator, StageId, now_ns};
use anyhow::{Context, Result, anyhow};
use iceoryx2::prelude::EventId;
use serde::Serialize;

/// What one stage process counted; written to
/// [`PipelineConfig::counters_path`] when it stops so the launcher can
/// report where frames were lost.
#[derive(Debug, Default, Serialize)]
struct Counters {
    stage: &'static str,
    pid: u32,
    /// Results published.
    processed: u64,
    /// Sequence numbers that never reached this stage's input: dropped
    /// upstream (a full queue lost its oldest sample) or never produced.
    input_gaps: u64,
    /// Inputs whose frame was no longer available (released from the
    /// history or never received): dropped here rather than processed
    /// without pixels.
    frames_missing: u64,
    /// Frames released from the history without having been looked up.
    history_released_unread: u64,
    /// Inputs whose sequence was not above the previous one (a source that
    /// restarted its numbering).
    sequence_resets: u64,
    /// Frames the stage skipped because their size was not the pipeline's.
    size_skipped: u64,
}

impl Counters {
    /// Counts the gap before input `seq`.
    fn input(&mut self, last: &mut Option<u64>, seq: u64) {
        match *last {
            Some(l) if seq > l => self.input_gaps += seq - l - 1,
            Some(_) => self.sequence_resets += 1,
            None => {}
        }
        *last = Some(seq);
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
    /// Frames skipped because their size was not the pipeline's.
    fn skipped(&self) -> u64 {
        0
    }
    /// Called after publishing (the seeding stage sends to zenoh here).
    fn sink(&mut self, _msg: &ResultMsg) -> Result<()> {
        Ok(())
    }
}

pub(super) fn announce_ready(ipc: &Ipc, id: StageId) -> Result<()> {
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
    cfg.pin_stage()?;
    if cfg.realtime_priority > 0 {
        // Later stages above earlier ones (capture stays at the base): a
        // frame further down the chain is finished before the next one
        // starts, and capture's rendering never holds up a woken stage.
        let p = cfg.realtime_priority + id as u8;
        acch_ipc::sched::set_fifo(p)
            .with_context(|| format!("{}: SCHED_FIFO priority {p}", id.name()))?;
    }
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
    let frames = if from_frames {
        Some(ipc.frame_stage_input()?)
    } else if S::NEEDS_FRAME && !copying {
        Some(ipc.frame_input(false)?)
    } else {
        None
    };
    let results = if from_frames {
        None
    } else {
        Some(ipc.result_stage_input(upstream)?)
    };
    let output = ipc.result_output(id, stage.payload_len())?;
    let mut history = FrameHistory::new(cfg.frame_history);
    let mut locator = ShmLocator::new();
    announce_ready(&ipc, id)?;
    tracing::debug!("{} ready", id.name());
    let mut counters = Counters {
        stage: id.name(),
        pid: std::process::id(),
        ..Default::default()
    };
    let mut last_in = None;
    while ipc.keep_running() {
        // Asleep until the upstream stage's wake-up or a stop signal.
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
                counters.input(&mut last_in, msg.sequence);
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
                if S::NEEDS_FRAME && frame.is_none() {
                    // The pixels are gone (released, or lost while this
                    // stage restarted): drop the frame, never guess.
                    counters.frames_missing += 1;
                    continue;
                }
                publish(&mut stage, &output, &mut msg, received, s.payload(), frame)?;
            } else {
                let Some(f) = frames.as_ref().map(|f| f.receive()).transpose()?.flatten() else {
                    break;
                };
                msg = ResultMsg::from_frame(f.user_header());
                counters.input(&mut last_in, msg.sequence);
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
                if frame.is_none() {
                    counters.frames_missing += 1;
                    continue;
                }
                publish(&mut stage, &output, &mut msg, received, &[], frame)?;
            }
            stage.sink(&msg)?;
            counters.processed += 1;
        }
    }
    counters.history_released_unread = history.dropped;
    counters.size_skipped = stage.skipped();
    tracing::info!("{}: {counters:?}", id.name());
    let path = cfg.counters_path(id.name(), counters.pid);
    if let Err(e) = std::fs::write(&path, serde_json::to_vec(&counters)?) {
        tracing::warn!("writing {}: {e}", path.display());
    }
    Ok(())
}

/// Runs the stage on one input, writing its payload straight into a
/// shared-memory loan, stamps the trail and publishes; `msg` ends as sent.
fn publish<S: Stage>(
    stage: &mut S,
    output: &Output<ResultMsg>,
    msg: &mut ResultMsg,
    received: u64,
    input: &[u8],
    frame: Option<&[u8]>,
) -> Result<()> {
    let id = S::ID as usize;
    output.send_in_place(stage.payload_len(), |payload, header| {
        stage.process(msg, input, frame, payload);
        msg.trail.stages[id].received_ns = received;
        msg.trail.stages[id].published_ns = now_ns();
        *header = *msg;
    })?;
    Ok(())
}

/// Counts a frame read, and whether it found the pixels where capture
/// wrote them (same shared-memory file and offset: not copied).
fn in_place(locator: &mut ShmLocator, msg: &mut ResultMsg, f: &acch_ipc::FrameSample) {
    let h = f.user_header();
    msg.frame_reads += 1;
    if locator.is_at(f.payload().as_ptr() as usize, (h.shm_file, h.shm_offset)) {
        msg.frame_reads_in_place += 1;
    }
}
