//! The viewer: what the pipeline sees, logged to rerun (`acch run
//! --rerun save:FILE.rrd | spawn | connect:URL`). Off the hot path: it
//! subscribes to the frames and to the segmentation (mask), pose (response)
//! and seeding (final result) services; nothing waits for it. When it falls
//! behind, iceoryx2 drops the oldest samples queued for it; the gaps are
//! counted, logged to `plot/dropped` and reported at exit.

use crate::PipelineConfig;
use crate::frame::FrameHeader;
use crate::node::{NodeError, announce_ready};
use crate::observe::{Gaps, Observe, ObserveError, Observer, Streams, lower_priority};
use crate::stages::{Posed, RegionPayload, ResponsePayload, Seeded, Segmented};
use crate::wire::{Hop, StageId};
use acch_viz::{Fused, Logger, ObjectSize, Observation, Pose, Rating, Sink, Truth};
use glam::{DAffine3, DQuat};
use serde::Serialize;
use std::time::Duration;

/// What the viewer logged and what it missed.
#[derive(Serialize, Debug, Default)]
pub struct VizSummary {
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
            } => log.mask((sequence, capture_ns), (width, height), &mask),
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

/// A column-major 3x4 `camera_from_object` as a pose.
pub(super) fn pose_of(camera_from_object: &[f64; 12]) -> Pose {
    let a = DAffine3::from_cols_array(camera_from_object);
    Pose {
        translation: a.translation.to_array(),
        rotation_xyzw: DQuat::from_mat3(&a.matrix3).normalize().to_array(),
    }
}

/// The viewer's view of a final result.
fn observation(m: &Seeded) -> Observation {
    let e = m.envelope();
    // Captured -> each stage published: cumulative, so the lines stack.
    let since_capture_ms = StageId::ALL
        .iter()
        .map(|s| {
            let ns = e
                .trail
                .of(*s)
                .published_ns
                .saturating_sub(e.trail.captured_ns);
            (s.name(), ns as f64 / 1e6)
        })
        .collect();
    let wide = |r: [u32; 4]| r.map(u64::from);
    Observation {
        sequence: e.frame.sequence,
        capture_ns: e.trail.captured_ns,
        window: m.detection().done().map(|w| wide(w.window.to_array())),
        roi: m.region().done().map(|r| wide(r.to_array())),
        estimate_deg: m
            .pose()
            .done()
            .map(|p| [p.theta_deg as f64, p.phi_deg as f64]),
        rating: m.rating().verdict().map(|v| Rating {
            confidence: v.confidence as f64,
            threshold: v.threshold as f64,
            accepted: v.accepted,
        }),
        seed: m.seed().filter(|_| m.accepted()).map(|s| Pose {
            translation: s.translation,
            rotation_xyzw: s.rotation_xyzw,
        }),
        fused: m.seeding.fused.get().map(|f| Fused {
            view_deg: f.view_deg,
            pose: pose_of(&f.camera_from_object),
        }),
        truth: e.frame.truth.get().map(|t| Truth {
            theta_deg: t.theta_deg,
            phi_deg: t.phi_deg,
            pose: pose_of(&t.camera_from_object),
        }),
        since_capture_ms,
    }
}

/// The viewer's side of each sample: queued for the logging thread, or
/// counted when the queue is full.
pub struct Viewing {
    s: VizSummary,
    /// Views of the database (responses have one value each).
    views: usize,
    tx: std::sync::mpsc::SyncSender<Item>,
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

impl Observe for Viewing {
    fn frame(&mut self, h: &FrameHeader, pixels: &[u8]) -> Result<(), ObserveError> {
        if !pixels.is_empty() {
            let f = &h.envelope.frame;
            let item = Item::Frame {
                sequence: f.sequence,
                capture_ns: h.envelope.trail.captured_ns,
                width: f.width,
                height: f.height,
                intrinsics: f.intrinsics.to_array(),
                rgb: pixels.to_vec(),
            };
            self.s.frames += u64::from(queue(&self.tx, item, &mut self.s.frames_queue_full));
        }
        Ok(())
    }

    fn region(&mut self, h: &Segmented, payload: &[u8]) -> Result<(), ObserveError> {
        if let Ok(Some(region)) = RegionPayload::read(h, payload) {
            let e = h.envelope();
            let mut mask = Vec::new();
            region.frame_mask(e.frame.width, e.frame.height, &mut mask);
            let item = Item::Mask {
                sequence: e.frame.sequence,
                capture_ns: e.trail.captured_ns,
                width: e.frame.width,
                height: e.frame.height,
                mask,
            };
            self.s.masks += u64::from(queue(&self.tx, item, &mut self.s.masks_queue_full));
        }
        Ok(())
    }

    fn response(&mut self, h: &Posed, payload: &[u8]) -> Result<(), ObserveError> {
        if let Ok(Some(r)) = ResponsePayload::read(h, self.views, payload) {
            let e = h.envelope();
            let item = Item::Response {
                sequence: e.frame.sequence,
                capture_ns: e.trail.captured_ns,
                values: r.values().collect(),
            };
            self.s.responses += u64::from(queue(&self.tx, item, &mut self.s.responses_queue_full));
        }
        Ok(())
    }

    fn results_start(&mut self, _gaps: &[Gaps; 4]) {
        self.last = None;
    }

    fn result(&mut self, m: &Seeded) -> Result<(), ObserveError> {
        let item = Item::Observation(Box::new(observation(m)));
        self.s.results += u64::from(queue(&self.tx, item, &mut self.s.results_queue_full));
        let e = m.envelope();
        self.last = Some((e.frame.sequence, e.trail.captured_ns));
        Ok(())
    }

    /// Logs the dropped count after every pass with a result: one scalar,
    /// so the plot spans the run.
    fn results_end(&mut self, gaps: &[Gaps; 4]) -> Result<(), ObserveError> {
        if let Some((sequence, capture_ns)) = self.last {
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

impl Viewing {
    /// A viewer logging to `sink` (`save:FILE.rrd`, `spawn`, `connect:URL`)
    /// for a database whose views are `views` (θ, φ degrees), the object
    /// drawn at a size read off its distance ([`ObjectSize::FromDistance`]).
    pub fn open(
        sink_arg: &str,
        views: &[(f32, f32)],
    ) -> Result<(Self, ViewerThread), ObserveError> {
        Self::open_sized(sink_arg, views, ObjectSize::FromDistance)
    }

    /// As [`Viewing::open`], the object drawn at `size`; rerun's logging
    /// runs on a thread of its own behind a bounded queue.
    pub fn open_sized(
        sink_arg: &str,
        views: &[(f32, f32)],
        size: ObjectSize,
    ) -> Result<(Self, ViewerThread), ObserveError> {
        let sink = Sink::parse(sink_arg)?;
        let stages = StageId::ALL.map(StageId::name);
        let log = Logger::new(sink.open("acch")?, views, size, &stages)?;
        // rerun's log() blocks when its sink cannot keep up (a stalled or
        // absent viewer): it runs on its own thread behind a bounded queue,
        // and what does not fit is dropped and counted here.
        let (tx, rx) = std::sync::mpsc::sync_channel::<Item>(QUEUE);
        let (done_tx, done_rx) = std::sync::mpsc::channel::<()>();
        let name = sink_arg.to_owned();
        let logger = std::thread::spawn(move || log_items(log, rx, &name, done_tx));
        Ok((
            Viewing {
                s: VizSummary {
                    sink: sink_arg.to_owned(),
                    ..Default::default()
                },
                views: views.len(),
                tx,
                last: None,
            },
            ViewerThread { logger, done_rx },
        ))
    }

    /// Closes the queue, lets the logging thread flush (3 s at most: a
    /// viewer that went away must not keep the run waiting) and returns
    /// the counts, with `missed` (frames, masks, responses, results) from
    /// the streams.
    pub fn finish(self, thread: ViewerThread, missed: [u64; 4]) -> VizSummary {
        let Viewing { mut s, tx, .. } = self;
        [
            s.frames_missed,
            s.masks_missed,
            s.responses_missed,
            s.results_missed,
        ] = missed;
        drop(tx);
        match thread.done_rx.recv_timeout(Duration::from_secs(3)) {
            Ok(()) => {
                let _ = thread.logger.join();
            }
            Err(_) => {
                s.unflushed = true;
                tracing::warn!(
                    "viz: rerun sink {} did not take the last data in 3 s",
                    s.sink
                );
            }
        }
        s
    }
}

/// The viewer's logging thread.
pub struct ViewerThread {
    logger: std::thread::JoinHandle<()>,
    done_rx: std::sync::mpsc::Receiver<()>,
}

/// Runs the viewer process until SIGINT, then drains what is queued,
/// flushes the sink and prints its counts.
pub fn run_viz(cfg: &PipelineConfig) -> Result<VizSummary, NodeError> {
    let sink_arg = cfg
        .observers
        .rerun
        .clone()
        .ok_or(crate::config::ConfigError::Invalid {
            key: "observers.rerun",
            value: String::new(),
            why: "the viz process needs a rerun sink",
        })?;
    lower_priority(Observer::Viz);
    let views = super::view_angles(&cfg.database()?);
    let ipc = cfg.ipc("viz")?;
    let mut streams = Streams::open(&ipc, cfg.run.frame_history)?;
    // The configured object's real radius sizes its box and axes.
    let size = super::record::object_size(cfg);
    let (mut out, thread) = Viewing::open_sized(&sink_arg, &views, size)?;
    announce_ready(&ipc, Observer::Viz.ready_id())?;
    streams.observe_until_stopped(&ipc, &mut out)?;
    let s = out.finish(thread, streams.missed());
    let skipped = s.frames_missed + s.frames_queue_full;
    if skipped + s.results_missed + s.results_queue_full > 0 {
        tracing::warn!(
            "viz: {skipped} frames and {} results skipped to keep up",
            s.results_missed + s.results_queue_full
        );
    }
    eprintln!(
        "acch viz summary: {}",
        serde_json::to_string(&s).expect("counts serialise")
    );
    Ok(s)
}
