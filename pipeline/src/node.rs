//! The process-per-stage executor: one stage (or capture) as a process,
//! connected over iceoryx2. A stage process sleeps on its input's wake-up
//! word, takes each sample, runs [`step`] on it with its output loaned
//! from shared memory, and publishes; capture writes each frame once into
//! shared memory. Started by the [`supervisor`](crate::supervisor).

use crate::config::{ConfigError, Pace, PipelineConfig};
use crate::copy::{self, CopyError};
use crate::frame::FrameHeader;
use crate::observe::ObserveError;
use crate::source::{Pixels, Produced, Source};
use crate::source_error::{CameraCounters, SourceError};
use crate::stage::{Stage, StageCounters, step};
use crate::stages::{BuildError, Seeded};
use crate::streams;
use crate::wire::{Hop, StageId};
use acch_ipc::{Ipc, IpcError, ShmLocator, Wake, now_ns};
use serde::Serialize;
use std::time::{Duration, Instant};

/// How long a process sleeps on its input before checking for a stop.
pub const WAIT: Duration = Duration::from_millis(200);

/// The control event every process announces its readiness on.
pub const READY: &str = "ready";
/// The control event that starts the capture.
pub const START: &str = "start";

/// Why a stage or capture process failed.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// The configuration is unusable.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The stage could not be built.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// iceoryx2 or zenoh failed.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The frame source failed.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// A sink failed.
    #[error(transparent)]
    Observe(#[from] ObserveError),
    /// The copy transport failed.
    #[error(transparent)]
    Copy(#[from] CopyError),
    /// Placement or scheduling was refused.
    #[error("{what}")]
    Sched {
        /// What was asked for.
        what: String,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
    /// The capture's source thread panicked.
    #[error("the capture source thread panicked")]
    SourcePanicked,
}

impl From<acch_ipc::NodeError> for NodeError {
    fn from(e: acch_ipc::NodeError) -> Self {
        NodeError::Ipc(e.into())
    }
}

impl From<acch_ipc::OpenError> for NodeError {
    fn from(e: acch_ipc::OpenError) -> Self {
        NodeError::Ipc(e.into())
    }
}

impl From<acch_ipc::SendError> for NodeError {
    fn from(e: acch_ipc::SendError) -> Self {
        NodeError::Ipc(e.into())
    }
}

impl From<acch_ipc::ReceiveError> for NodeError {
    fn from(e: acch_ipc::ReceiveError) -> Self {
        NodeError::Ipc(e.into())
    }
}

impl From<acch_ipc::WaitError> for NodeError {
    fn from(e: acch_ipc::WaitError) -> Self {
        NodeError::Ipc(e.into())
    }
}

/// What one stage process counted; written to
/// [`PipelineConfig::counters_path`] when it stops, so the launcher can
/// report where frames were lost.
#[derive(Debug, Serialize)]
pub struct NodeCounters {
    /// The stage's own counters (published, faults by kind).
    #[serde(flatten)]
    pub stage: StageCounters,
    /// Its process.
    pub pid: u32,
    /// Sequence numbers that never reached its input: dropped upstream (a
    /// full queue lost its oldest sample) or never produced.
    pub input_gaps: u64,
    /// Inputs dropped rather than processed without their pixels: the
    /// frame copy never arrived (copy transport), or, for a stage that
    /// reads the frame beside its input, the frame had left the queue.
    pub frames_missing: u64,
    /// Inputs whose sequence was not above the previous one (a source that
    /// restarted its numbering).
    pub sequence_resets: u64,
}

impl NodeCounters {
    fn new(id: StageId) -> Self {
        NodeCounters {
            stage: StageCounters::new(id),
            pid: std::process::id(),
            input_gaps: 0,
            frames_missing: 0,
            sequence_resets: 0,
        }
    }

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

/// What the capture process counted; written beside the stages' counters.
#[derive(Debug, Serialize)]
pub struct CaptureCounters {
    /// Always "capture".
    pub stage: &'static str,
    /// Its process.
    pub pid: u32,
    /// Frames published.
    pub sent: u64,
    /// Source frames skipped for having another size than the stream.
    pub skipped_size: u64,
    /// What a camera source lost (all zero for the others).
    pub camera: CameraCounters,
}

/// Writes counters `value` of process `name` where the launcher reads them.
fn write_counters(cfg: &PipelineConfig, name: &str, value: &impl Serialize) {
    let path = cfg.counters_path(name, std::process::id());
    let json = serde_json::to_vec(value).expect("counters serialise");
    if let Err(e) = std::fs::write(&path, json) {
        tracing::warn!("writing {}: {e}", path.display());
    }
}

/// Tells the launcher process `id` is connected (it starts the capture
/// only when every stage and observer is).
pub fn announce_ready(ipc: &Ipc, id: usize) -> Result<(), NodeError> {
    ipc.control_notifier(READY)?.notify(id)?;
    Ok(())
}

/// Pins this process to the stages' CPUs and, under `realtime_priority`,
/// raises it above the stages before it: a frame further down the chain is
/// finished before the next one starts, and capture's rendering never holds
/// up a woken stage.
fn place(cfg: &PipelineConfig, id: StageId) -> Result<(), NodeError> {
    cfg.pin_stage().map_err(|source| NodeError::Sched {
        what: format!(
            "run.stage_cpus = {}: pinning {}",
            cfg.run.stage_cpus,
            id.name()
        ),
        source,
    })?;
    if cfg.run.realtime_priority > 0 {
        let p = cfg.run.realtime_priority + id as u8;
        acch_ipc::sched::set_fifo(p).map_err(|source| NodeError::Sched {
            what: format!("{}: SCHED_FIFO priority {p}", id.name()),
            source,
        })?;
    }
    Ok(())
}

/// Runs `stage` as its process until SIGINT/SIGTERM: connect, announce
/// readiness, then for every input sample (sleeping on the input's wake-up
/// word in between) run the stage into a shared-memory loan and publish;
/// `sink` then sees each published header (seeding's zenoh publisher).
pub fn run_stage<S: Stage>(
    cfg: &PipelineConfig,
    mut stage: S,
    mut sink: impl FnMut(&S::Output) -> Result<(), ObserveError>,
) -> Result<NodeCounters, NodeError> {
    let id = S::ID;
    place(cfg, id)?;
    let ipc = cfg.ipc(id.name())?;
    let spec = streams::input_of(id, cfg.run.frame_history).expect("a processing stage");
    // The copy baseline: pixels arrive on recognition's socket; the frame
    // stream then only carries their headers and wake-ups.
    let mut copies = (cfg.copies_frames() && id == StageId::Recognition)
        .then(|| copy::FrameReceiver::bind(&copy::socket_path(cfg), cfg.run.frame_history))
        .transpose()?;
    let input = ipc.input::<S::Input>(spec, Wake::Word)?;
    // A stage that reads the frame beside its input (pose) takes it from
    // the frame stream, in place: the frame of a result's sequence was
    // published before the result, so it is queued when the result comes.
    let frames = (S::READS_FRAME && id != StageId::Recognition)
        .then(|| ipc.input::<FrameHeader>(streams::frames(cfg.run.frame_history), Wake::Never))
        .transpose()?;
    let mut held: Option<acch_ipc::Received<FrameHeader>> = None;
    let output = ipc.output::<S::Output>(streams::results(id), stage.max_payload())?;
    let mut locator = ShmLocator::new();
    announce_ready(&ipc, id as usize)?;
    tracing::debug!("{} ready", id.name());
    let mut counters = NodeCounters::new(id);
    let mut last_in = None;
    let len = stage.max_payload();
    while ipc.keep_running() {
        // Asleep until the upstream stage's wake-up or a stop signal.
        input.wait(WAIT)?;
        while let Some(sample) = input.receive()? {
            let mut header = *sample.user_header();
            let sequence = header.envelope().frame.sequence;
            counters.input(&mut last_in, sequence);
            let (payload, received) = match &mut copies {
                Some(c) => {
                    header.envelope_mut().reads.reads += 1;
                    // The hop ends when the copy is in this process.
                    let Some(pixels) = c.take(sequence, WAIT) else {
                        counters.frames_missing += 1;
                        continue;
                    };
                    (pixels, now_ns())
                }
                None => {
                    let received = now_ns();
                    let payload = sample.payload();
                    if let Some(at) = header.pixels_at() {
                        let reads = &mut header.envelope_mut().reads;
                        reads.reads += 1;
                        if locator.is_at(payload.as_ptr() as usize, at) {
                            reads.in_place += 1;
                        }
                    }
                    (payload, received)
                }
            };
            let pixels: &[u8] = match &frames {
                None => &[],
                Some(f) => {
                    while held
                        .as_ref()
                        .is_none_or(|h| h.user_header().envelope.frame.sequence < sequence)
                    {
                        match f.receive()? {
                            Some(s) => held = Some(s),
                            None => break,
                        }
                    }
                    match &held {
                        Some(h) if h.user_header().envelope.frame.sequence == sequence => {
                            h.payload()
                        }
                        _ => {
                            // Dropped from the frame queue (a restarted
                            // stage subscribes anew): the result is
                            // dropped and counted. Without its pixels the
                            // pose could not be verified, and an
                            // unverified pose falls back to the colour
                            // rules, which real photographs showed accept
                            // wrong poses.
                            counters.frames_missing += 1;
                            continue;
                        }
                    }
                }
            };
            let mut sent = S::Output::default();
            output
                .send_in_place(len, |out, h| {
                    *h = step(
                        &mut stage,
                        &header,
                        payload,
                        pixels,
                        out,
                        received,
                        &mut counters.stage,
                    );
                    sent = *h;
                    Ok::<(), std::convert::Infallible>(())
                })?
                .unwrap_or_else(|never| match never {});
            sink(&sent)?;
        }
    }
    tracing::debug!("{}: {counters:?}", id.name());
    write_counters(cfg, id.name(), &counters);
    Ok(counters)
}

/// Frames the source may have ready beyond the one being published.
const READ_AHEAD: usize = 1;
/// Frames a free-running replay lets into the pipeline at once (the frame
/// and result queues hold more, so none is dropped).
const IN_FLIGHT: u64 = 2;
/// A free-running replay stops waiting for a result after this long (a
/// frame a stage dropped must not stall the replay).
const RESULT_WAIT: Duration = Duration::from_secs(2);

/// Runs the capture process: waits for the launcher's start signal, then
/// writes `camera.frames` frames into shared memory at `camera.fps` (or
/// a recording's pace) and stays until terminated (subscribers may still
/// hold its samples).
pub fn run_capture(cfg: &PipelineConfig) -> Result<(), NodeError> {
    let ipc = cfg.ipc("capture")?;
    let (w, h) = cfg.frame_size()?;
    let output = ipc.output::<FrameHeader>(
        streams::frames(cfg.run.frame_history),
        3 * w as usize * h as usize,
    )?;
    let start = ipc.control_listener(START)?;
    let spec = cfg.source_spec()?;
    let source = Source::open(&spec, (w, h), cfg.camera.first_frame)?;
    let stop_source = source.stop_flag();
    let arm = crate::ros2::ArmFeed::open(&cfg.ros2, &cfg.zenoh).map_err(ObserveError::from)?;
    let pace = cfg.pace();
    // A free-running replay, and a stream that waits for its reader (a
    // file through GStreamer: nothing of it may be dropped), watch the
    // final results to pace themselves ...
    let waits_for_results =
        pace == Some(Pace::Free) || (pace == Some(Pace::Source) && !source.is_live());
    let done = waits_for_results
        .then(|| ipc.input::<Seeded>(streams::results(StageId::Seeding), Wake::Event))
        .transpose()?;
    // ... and, when a recorder runs, what it has recorded (a replay
    // recorded again must lose nothing): it notifies "recorded" after each
    // result, with the sequence modulo acch_record::RECORDED_IDS as the
    // event id so notifications of different frames do not merge.
    let recorded = (done.is_some() && cfg.observers.record.is_some())
        .then(|| ipc.control_listener(acch_record::RECORDED_EVENT))
        .transpose()?;
    // The source (rendering, decoding, reading) runs ahead on a thread of
    // its own, which keeps the launcher's CPUs, as a camera exposes and
    // reads out a frame on its own; this thread only publishes, from the
    // stages' CPU, so the wake-up of recognition is a local one.
    let (frames_tx, frames_rx) = std::sync::mpsc::sync_channel::<Produced>(READ_AHEAD);
    let (recycle_tx, recycle_rx) = std::sync::mpsc::channel::<Pixels>();
    let (first, frames, realtime) = (
        cfg.camera.first_frame,
        cfg.camera.frames,
        cfg.run.realtime_priority > 0,
    );
    let producer = std::thread::Builder::new()
        .name("capture-source".into())
        .spawn(move || produce(source, first, frames, realtime, &frames_tx, &recycle_rx))
        .map_err(|source| NodeError::Sched {
            what: "starting the capture source thread".into(),
            source,
        })?;
    place(cfg, StageId::Capture)?;
    announce_ready(&ipc, StageId::Capture as usize)?;
    // Wait for the launcher: every subscriber is connected.
    let mut go = false;
    while !go && ipc.keep_running() {
        start.take(WAIT, |_| go = true)?;
    }
    // The copy baseline: connect to recognition's socket (it is bound
    // before recognition announces readiness).
    let mut copies = cfg
        .copies_frames()
        .then(|| copy::FrameSender::connect(&[copy::socket_path(cfg)]))
        .transpose()?;
    let mut locator = ShmLocator::new();
    let t0 = Instant::now();
    // Frames sent, results seen (free replay). A restarted capture
    // continues where the run is (`first_frame`).
    let mut i = cfg.camera.first_frame;
    let (mut finished, mut logged) = (cfg.camera.first_frame, cfg.camera.first_frame);
    let mut first_recorded = None;
    while ipc.keep_running() && (cfg.camera.frames == 0 || i < cfg.camera.frames) {
        if cfg.camera.fps > 0.0 && pace.is_none() {
            let due =
                t0 + Duration::from_secs_f64((i - cfg.camera.first_frame) as f64 / cfg.camera.fps);
            sleep_until(due);
        }
        if let Some(d) = &done {
            let mut since = Instant::now();
            loop {
                let behind_results = i >= finished + IN_FLIGHT;
                let behind_record = recorded.is_some() && i >= logged + IN_FLIGHT;
                if !(behind_results || behind_record) || !ipc.keep_running() {
                    break;
                }
                if behind_results {
                    d.wait(WAIT.min(RESULT_WAIT))?;
                    while d.receive()?.is_some() {
                        finished += 1;
                    }
                } else if let Some(l) = &recorded {
                    l.take(WAIT, |_| logged += 1)?;
                }
                if since.elapsed() > RESULT_WAIT {
                    tracing::warn!("capture: no result for {RESULT_WAIT:?}: sending on");
                    finished = finished.max(i + 1 - IN_FLIGHT);
                    logged = logged.max(i + 1 - IN_FLIGHT);
                    since = Instant::now();
                }
            }
        }
        // The source is done (or failed: its error is returned below).
        let Ok(Produced {
            mut header,
            pixels,
            recorded_ns,
            captured_ns,
            taken_ns,
        }) = frames_rx.recv()
        else {
            break;
        };
        if let (Some(Pace::Recorded), Some(t)) = (pace, recorded_ns) {
            // The recording's frame times, from the first frame's.
            let first = *first_recorded.get_or_insert(t);
            sleep_until(t0 + Duration::from_nanos(t.saturating_sub(first)));
        }
        // The frame exists now, or when the camera says it captured it;
        // capture's own span is the publishing (rendering or decoding it
        // ran ahead, `taken_ns` long, and is not part of the frame's
        // latency).
        let captured = captured_ns.unwrap_or_else(now_ns);
        header.stamp_captured(captured);
        if let Some(arm) = &arm {
            arm.stamp(&mut header, captured);
        }
        tracing::trace!("frame {i}: source took {taken_ns} ns");
        if let Some(tx) = &mut copies {
            // Published = the copy starts; the header follows on iceoryx2
            // with no pixels.
            header.envelope.trail.stages[0].published_ns = now_ns();
            tx.send(header.envelope.frame.sequence, pixels.bytes())?;
            output.send(&[], |h, _| *h = header)?;
        } else {
            output.send(pixels.bytes(), |h, addr| {
                let (file, offset) = locator.locate(addr).unwrap_or_default();
                header.location = crate::frame::ShmLocation { file, offset };
                header.envelope.trail.stages[0].published_ns = now_ns();
                *h = header;
            })?;
        }
        // Back to the source for the next frame (no allocation per frame).
        let _ = recycle_tx.send(pixels);
        i += 1;
    }
    // Stops a source still rendering ahead (or a camera waiting for a
    // frame), then reports how it ended.
    if let Some(stop) = &stop_source {
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
    drop(frames_rx);
    let ended = producer.join().map_err(|_| NodeError::SourcePanicked)?;
    // A source that fails (an unreadable image, a corrupt recording) ends
    // the stream; say why.
    let (skipped_size, camera) = ended?;
    let sent = i - cfg.camera.first_frame;
    tracing::info!("capture: {sent} frames sent");
    write_counters(
        cfg,
        "capture",
        &CaptureCounters {
            stage: "capture",
            pid: std::process::id(),
            sent,
            skipped_size,
            camera,
        },
    );
    while ipc.keep_running() {
        std::thread::sleep(WAIT);
    }
    Ok(())
}

/// The source thread: makes frames `first ..` in order and hands them over
/// (blocking while [`READ_AHEAD`] wait). Returns, with the frames it
/// skipped for their size and what a camera lost, when the run's frames
/// are made, the source ends, or the publisher hangs up.
fn produce(
    mut source: Source,
    first: u64,
    frames: u64,
    realtime: bool,
    out: &std::sync::mpsc::SyncSender<Produced>,
    recycle: &std::sync::mpsc::Receiver<Pixels>,
) -> Result<(u64, CameraCounters), SourceError> {
    if realtime && !source.renders() {
        // Reading the camera is not the real-time path.
        if let Err(e) = acch_ipc::sched::set_normal() {
            tracing::warn!("capture source: could not leave SCHED_FIFO: {e}");
        }
    }
    // A real camera exposes and reads out in its own hardware; the
    // synthetic camera's rendering stands in for that and renders the next
    // frame while the stages work on this one. It yields to them, and to
    // the pose stage's fit helper beside them (pipeline/src/stages/pose.rs).
    if source.renders()
        && let Err(e) = acch_ipc::sched::set_idle()
    {
        tracing::warn!("capture source: rendering not moved to SCHED_IDLE: {e}");
    }
    let mut i = first;
    while frames == 0 || i < frames {
        for p in recycle.try_iter() {
            source.recycle(p);
        }
        let Some(p) = source.next_frame()? else { break };
        if out.send(p).is_err() {
            break;
        }
        i += 1;
    }
    if source.skipped > 0 {
        tracing::warn!("capture: {} frames skipped for their size", source.skipped);
    }
    let camera = source.camera_counters();
    if camera != Default::default() {
        tracing::warn!(
            "capture: the camera dropped {} frames, {} were lost in {} failures",
            camera.dropped,
            camera.lost,
            camera.failures
        );
    }
    Ok((source.skipped, camera))
}

fn sleep_until(due: Instant) {
    if let Some(wait) = due.checked_duration_since(Instant::now()) {
        std::thread::sleep(wait);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn input_gaps_and_resets_are_counted() {
        let mut c = NodeCounters::new(StageId::Pose);
        let mut last = None;
        for s in [0, 1, 4, 5, 2, 9] {
            c.input(&mut last, s);
        }
        // 1 -> 4 skips two; after the reset to 2, 2 -> 9 skips six.
        assert_eq!(c.input_gaps, 2 + 6);
        assert_eq!(c.sequence_resets, 1);
    }
}
