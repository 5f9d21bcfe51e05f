//! The `viz` process: what the pipeline sees, logged to rerun (`acch run
//! --rerun save:FILE.rrd | spawn | connect:URL`). Off the hot path: it
//! subscribes to the frames and to the segmentation (mask), pose (response)
//! and seeding (final result) services; nothing waits for it. When it falls
//! behind, iceoryx2 drops the oldest samples queued for it; the gaps are
//! counted, logged to `viz/dropped` and reported at exit.

use super::observe::{
    Gaps, Observe, Streams, announce_ready, frame_mask, lower_priority, response_values,
};
use crate::stages::PipelineConfig;
use acch_core::ViewDatabase;
use acch_ipc::{FrameHeader, Observer, ResultMsg, StageId};
use acch_viz::{Logger, Observation, Sink, Truth};
use anyhow::{Result, anyhow};
use glam::{DAffine3, DQuat};
use serde::Serialize;
use std::time::Duration;

/// What the viewer logged and what it missed.
#[derive(Serialize, Debug, Default)]
struct VizSummary {
    sink: String,
    frames: u64,
    masks: u64,
    responses: u64,
    results: u64,
    frames_missed: u64,
    masks_missed: u64,
    responses_missed: u64,
    results_missed: u64,
    /// Received but not logged: the logging queue was full (rerun blocked).
    frames_queue_full: u64,
    masks_queue_full: u64,
    responses_queue_full: u64,
    results_queue_full: u64,
    /// The sink had not taken everything when the process had to exit.
    unflushed: bool,
}

/// Items queued for the logging thread.
const QUEUE: usize = 16;

/// What the logging thread logs.
enum Item {
    Frame {
        sequence: u64,
        capture_ns: u64,
        width: u32,
        height: u32,
        intrinsics: [f64; 4],
        rgb: Vec<u8>,
    },
    Mask {
        sequence: u64,
        capture_ns: u64,
        width: u32,
        height: u32,
        mask: Vec<u8>,
    },
    Response {
        sequence: u64,
        capture_ns: u64,
        values: Vec<f32>,
    },
    Observation(Box<Observation>),
    Dropped {
        sequence: u64,
        capture_ns: u64,
        dropped: u64,
    },
}

/// The logging thread: logs every queued item until the queue closes,
/// then flushes and says so on `done`.
fn log_items(
    mut log: Logger,
    rx: std::sync::mpsc::Receiver<Item>,
    sink: &str,
    done: std::sync::mpsc::Sender<()>,
) {
    let mut errors = 0u64;
    for item in rx {
        let r = match item {
            Item::Frame {
                sequence,
                capture_ns,
                width,
                height,
                intrinsics,
                rgb,
            } => log.frame(sequence, capture_ns, width, height, intrinsics, &rgb),
            Item::Mask {
                sequence,
                capture_ns,
                width,
                height,
                mask,
            } => log.mask(sequence, capture_ns, width, height, &mask),
            Item::Response {
                sequence,
                capture_ns,
                values,
            } => log.response(sequence, capture_ns, &values),
            Item::Observation(o) => log.observation(&o),
            Item::Dropped {
                sequence,
                capture_ns,
                dropped,
            } => log.dropped(sequence, capture_ns, dropped),
        };
        if let Err(e) = r {
            // Bad input is named once; the viewer keeps going.
            if errors == 0 {
                tracing::warn!("viz: {e}");
            }
            errors += 1;
        }
    }
    if let Err(e) = log.stream().flush_with_timeout(Duration::from_secs(2)) {
        tracing::warn!("viz: flushing rerun sink {sink}: {e}");
    }
    if errors > 1 {
        tracing::warn!("viz: {errors} items could not be logged");
    }
    let _ = done.send(());
}

/// The viewer's view of a final result.
fn observation(m: &ResultMsg) -> Observation {
    let stage_ms = StageId::ALL
        .iter()
        .map(|s| {
            let t = m.trail.stages[*s as usize];
            (
                s.name(),
                t.published_ns.saturating_sub(t.received_ns) as f64 / 1e6,
            )
        })
        .collect();
    let end = m.trail.stages[StageId::Seeding as usize].published_ns;
    Observation {
        sequence: m.sequence,
        capture_ns: m.trail.captured_ns,
        window: (m.found == 1).then_some(m.window),
        roi: (m.segmented == 1).then_some(m.roi),
        estimate_deg: (m.estimated == 1).then_some([m.estimate[0], m.estimate[1]]),
        confidence: (m.rated == 1).then_some(m.confidence),
        seed: (m.seeded == 1 && m.accepted == 1)
            .then_some((m.seed_translation, m.seed_rotation_xyzw)),
        truth: (m.truth.valid == 1).then(|| {
            let a = DAffine3::from_cols_array(&m.truth.camera_from_object);
            Truth {
                theta_deg: m.truth.theta_deg,
                phi_deg: m.truth.phi_deg,
                translation: a.translation.to_array(),
                rotation_xyzw: DQuat::from_mat3(&a.matrix3).normalize().to_array(),
            }
        }),
        stage_ms,
        end_to_end_ms: end.saturating_sub(m.trail.captured_ns) as f64 / 1e6,
    }
}

/// The viewer's side of each sample: queued for the logging thread, or
/// counted when the queue is full.
struct Viewing {
    s: VizSummary,
    tx: std::sync::mpsc::SyncSender<Item>,
    /// Samples missed before this pass's results (frames dropped included).
    missed_before: u64,
    /// This pass's last result: sequence, capture time.
    last: Option<(u64, u64)>,
}

/// Queues `item` for the logging thread; false (and `dropped` counted)
/// when the queue is full.
fn queue(tx: &std::sync::mpsc::SyncSender<Item>, item: Item, dropped: &mut u64) -> bool {
    match tx.try_send(item) {
        Ok(()) => true,
        Err(_) => {
            *dropped += 1;
            false
        }
    }
}

impl Viewing {
    /// Every sample missed so far, frames the queue had no room for included.
    fn missed(&self, gaps: &[Gaps; 4]) -> u64 {
        gaps.iter().map(|g| g.missed).sum::<u64>() + self.s.frames_queue_full
    }
}

impl Observe for Viewing {
    fn frame(&mut self, h: &FrameHeader, pixels: &[u8]) -> Result<()> {
        if !pixels.is_empty() {
            let item = Item::Frame {
                sequence: h.sequence,
                capture_ns: h.capture_ns,
                width: h.width as u32,
                height: h.height as u32,
                intrinsics: h.intrinsics,
                rgb: pixels.to_vec(),
            };
            self.s.frames += u64::from(queue(&self.tx, item, &mut self.s.frames_queue_full));
        }
        Ok(())
    }

    fn mask(&mut self, h: &ResultMsg, payload: &[u8]) -> Result<()> {
        let mut mask = Vec::new();
        if h.segmented == 1 && frame_mask(h, payload, &mut mask) {
            let item = Item::Mask {
                sequence: h.sequence,
                capture_ns: h.trail.captured_ns,
                width: h.width as u32,
                height: h.height as u32,
                mask,
            };
            self.s.masks += u64::from(queue(&self.tx, item, &mut self.s.masks_queue_full));
        }
        Ok(())
    }

    fn response(&mut self, h: &ResultMsg, payload: &[u8]) -> Result<()> {
        if h.estimated == 1 {
            let item = Item::Response {
                sequence: h.sequence,
                capture_ns: h.trail.captured_ns,
                values: response_values(payload),
            };
            self.s.responses += u64::from(queue(&self.tx, item, &mut self.s.responses_queue_full));
        }
        Ok(())
    }

    fn results_start(&mut self, gaps: &[Gaps; 4]) {
        self.missed_before = self.missed(gaps);
        self.last = None;
    }

    fn result(&mut self, m: &ResultMsg) -> Result<()> {
        let item = Item::Observation(Box::new(observation(m)));
        self.s.results += u64::from(queue(&self.tx, item, &mut self.s.results_queue_full));
        self.last = Some((m.sequence, m.trail.captured_ns));
        Ok(())
    }

    /// Logs the dropped count when it grew this pass (and on the first
    /// frame, so the series starts at 0).
    fn results_end(&mut self, gaps: &[Gaps; 4]) -> Result<()> {
        if let Some((sequence, capture_ns)) = self.last
            && (self.missed(gaps) != self.missed_before || sequence == 0)
        {
            let dropped = gaps[0].missed + self.s.frames_queue_full;
            queue(
                &self.tx,
                Item::Dropped {
                    sequence,
                    capture_ns,
                    dropped,
                },
                &mut 0,
            );
        }
        Ok(())
    }
}

/// Runs the viewer until SIGINT, then drains what is queued, flushes the
/// sink and prints its counts.
pub fn run(cfg: &PipelineConfig) -> Result<()> {
    let sink_arg = cfg
        .rerun
        .clone()
        .ok_or_else(|| anyhow!("the configuration names no rerun sink (rerun = ...)"))?;
    let sink = Sink::parse(&sink_arg)?;
    lower_priority(Observer::Viz);
    let db_path = cfg
        .db
        .as_ref()
        .ok_or_else(|| anyhow!("the configuration names no database (db = ...)"))?;
    let db = ViewDatabase::load(db_path)?;
    let views: Vec<(f32, f32)> = db
        .views()
        .iter()
        .map(|v| (v.theta_deg, v.phi_deg))
        .collect();
    drop(db);
    let ipc = cfg.ipc("viz")?;
    let mut streams = Streams::open(&ipc)?;
    let log = Logger::new(sink.open("acch")?, &views)?;
    // rerun's log() blocks when its sink cannot keep up (a stalled or
    // absent viewer): it runs on its own thread behind a bounded queue, and
    // what does not fit is dropped and counted here.
    let (tx, rx) = std::sync::mpsc::sync_channel::<Item>(QUEUE);
    let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
    let sink_name = sink_arg.clone();
    let logger = std::thread::spawn(move || log_items(log, rx, &sink_name, done_tx));
    announce_ready(&ipc, Observer::Viz)?;
    let mut out = Viewing {
        s: VizSummary {
            sink: sink_arg,
            ..Default::default()
        },
        tx,
        missed_before: 0,
        last: None,
    };
    streams.observe_until_stopped(&ipc, &mut out)?;
    let Viewing { mut s, tx, .. } = out;
    [
        s.frames_missed,
        s.masks_missed,
        s.responses_missed,
        s.results_missed,
    ] = streams.missed();
    drop(tx);
    // The logger thread finishes the queue and flushes; a viewer that went
    // away must not keep this process (or the run) waiting.
    match done_rx.recv_timeout(Duration::from_secs(3)) {
        Ok(()) => {
            let _ = logger.join();
        }
        Err(_) => {
            s.unflushed = true;
            tracing::warn!(
                "viz: rerun sink {} did not take the last data in 3 s",
                s.sink
            );
        }
    }
    let skipped = s.frames_missed + s.frames_queue_full;
    if skipped + s.results_missed + s.results_queue_full > 0 {
        tracing::warn!(
            "viz: {skipped} frames and {} results skipped to keep up",
            s.results_missed + s.results_queue_full
        );
    }
    eprintln!("acch viz summary: {}", serde_json::to_string(&s)?);
    Ok(())
}
