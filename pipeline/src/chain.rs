//! The in-process executor: the five stages chained on one thread, each
//! payload in a buffer of the chain's own. Every evaluation, `acch run
//! --in-process`, `acch estimate` and the benchmark's compute floor run
//! this, on the very stage values a stage process runs.

use crate::config::StageSettings;
use crate::frame::FrameHeader;
use crate::observe::{Observe, ObserveError};
use crate::source::Source;
use crate::source_error::SourceError;
use crate::stage::{Stage, StageCounters, step};
use crate::stages::{
    BuildError, Posed, Recognised, RecognitionPayload, RegionPayload, ResponsePayload, Seeded,
    Segmented, Stages,
};
use crate::wire::{Hop, StageId};
use acch_core::ViewDatabase;
use acch_ipc::now_ns;
use std::time::{Duration, Instant};

/// The five stages on one thread.
pub struct Chain {
    stages: Stages,
    /// Recognition's, segmentation's and pose's payloads of the last frame.
    buffers: [Vec<u8>; 3],
    counters: [StageCounters; 5],
    /// The last frame's headers, for the payload views.
    last: Option<Seeded>,
}

impl Chain {
    /// The chain of `stages`, with buffers sized for their payloads.
    pub fn new(stages: Stages) -> Self {
        let buffers = [
            vec![0; stages.recognition.max_payload()],
            vec![0; stages.segmentation.max_payload()],
            vec![0; stages.pose.max_payload()],
        ];
        let counters = [
            StageId::Recognition,
            StageId::Segmentation,
            StageId::Pose,
            StageId::Confidence,
            StageId::Seeding,
        ]
        .map(StageCounters::new);
        Chain {
            stages,
            buffers,
            counters,
            last: None,
        }
    }

    /// Every stage for `db` with `settings`, chained.
    pub fn build(db: &ViewDatabase, settings: &StageSettings) -> Result<Self, BuildError> {
        Ok(Self::new(Stages::new(db, settings)?))
    }

    /// Every stage for the sharp database `sharp` and, when given, the
    /// smoothed one `smoothed`, chosen per frame by recognition
    /// ([`crate::stages::BySet`]), chained.
    pub fn build_for_sets(
        sharp: &ViewDatabase,
        smoothed: Option<&ViewDatabase>,
        settings: &StageSettings,
    ) -> Result<Self, BuildError> {
        Ok(Self::new(Stages::for_sets(sharp, smoothed, settings)?))
    }

    /// The stages.
    pub fn stages(&self) -> &Stages {
        &self.stages
    }

    /// The stages, to change (a confidence threshold, say).
    pub fn stages_mut(&mut self) -> &mut Stages {
        &mut self.stages
    }

    /// The last frame's result.
    pub fn last(&self) -> Option<Seeded> {
        self.last
    }

    /// What each stage counted so far.
    pub fn counters(&self) -> &[StageCounters; 5] {
        &self.counters
    }

    /// Runs every stage on frame `frame` (packed RGB `rgb`). Its trail gets
    /// each stage's start and end; capture's times are the caller's.
    pub fn process(&mut self, frame: &FrameHeader, rgb: &[u8]) -> Seeded {
        let recognised = self.recognise(frame, rgb);
        self.finish(&recognised, rgb)
    }

    /// Recognition alone on frame `frame`: the window, before the later
    /// stages see it (several objects' windows are compared first, see
    /// `multi`). [`finish`](Self::finish) goes on from here.
    pub fn recognise(&mut self, frame: &FrameHeader, rgb: &[u8]) -> Recognised {
        let s = &mut self.stages.recognition;
        step(
            s,
            frame,
            rgb,
            &[],
            &mut self.buffers[0],
            now_ns(),
            &mut self.counters[0],
        )
    }

    /// [`recognise`](Self::recognise) on a frame whose indices under the
    /// database's palette `quantise` writes (through a joint palette
    /// shared with other objects' chains, `multi`): recognition
    /// quantises the frame itself only under another light.
    pub fn recognise_quantised(
        &mut self,
        frame: &FrameHeader,
        rgb: &[u8],
        quantise: impl FnOnce(&mut [u8]),
    ) -> Recognised {
        // Several objects' chains share a joint palette of their sharp
        // databases: they do not choose a set per frame.
        let s = self.stages.recognition.sharp_mut();
        quantise(&mut self.buffers[0][..s.pixels()]);
        s.indices_written();
        self.recognise(frame, rgb)
    }

    /// Segmentation, pose, confidence and seeding on what
    /// [`recognise`](Self::recognise) returned for the last frame (its
    /// detection may since have been withdrawn), whose pixels are `rgb`.
    pub fn finish(&mut self, recognised: &Recognised, rgb: &[u8]) -> Seeded {
        let [rec, seg, pose] = &mut self.buffers;
        let [_, c_seg, c_pose, c_conf, c_seed] = &mut self.counters;
        let s = &mut self.stages;
        let r = recognised;
        let g = step(&mut s.segmentation, r, rec, &[], seg, now_ns(), c_seg);
        let p = step(&mut s.pose, &g, seg, rgb, pose, now_ns(), c_pose);
        let c = step(&mut s.confidence, &p, pose, &[], &mut [], now_ns(), c_conf);
        let out = step(&mut s.seeding, &c, &[], &[], &mut [], now_ns(), c_seed);
        self.last = Some(out);
        out
    }

    /// [`process`](Self::process), then hands the frame, the region, the
    /// response and the result to `observer`, as the observer processes see
    /// them from shared memory.
    pub fn process_observed(
        &mut self,
        frame: &FrameHeader,
        rgb: &[u8],
        observer: &mut dyn Observe,
    ) -> Result<Seeded, ObserveError> {
        let out = self.process(frame, rgb);
        observer.frame(frame, rgb)?;
        let posed = &out.rated.posed;
        observer.region(&posed.segmented, &self.buffers[1])?;
        observer.response(posed, &self.buffers[2])?;
        observer.results_start(&Default::default());
        observer.result(&out)?;
        observer.results_end(&Default::default())?;
        Ok(out)
    }

    /// The last frame's raw payload of stage `id` (recognition,
    /// segmentation or pose; empty for the others).
    pub fn payload(&self, id: StageId) -> &[u8] {
        match id {
            StageId::Recognition => &self.buffers[0],
            StageId::Segmentation => &self.buffers[1],
            StageId::Pose => &self.buffers[2],
            _ => &[],
        }
    }

    fn last_headers(&self) -> Option<(&Recognised, &Segmented, &Posed)> {
        let s = self.last.as_ref()?;
        let posed = &s.rated.posed;
        Some((&posed.segmented.recognised, &posed.segmented, posed))
    }

    /// The last frame's palette indices and region counts.
    pub fn last_recognition(&self) -> Option<RecognitionPayload<'_>> {
        let (r, _, _) = self.last_headers()?;
        let layout = self.stages.segmentation.last_used().layout();
        RecognitionPayload::read(r, layout, &self.buffers[0]).ok()
    }

    /// The last frame's mask and indices over its region, if one was grown.
    pub fn last_region(&self) -> Option<RegionPayload<'_>> {
        let (_, g, _) = self.last_headers()?;
        RegionPayload::read(g, &self.buffers[1]).ok().flatten()
    }

    /// The last frame's response, if an estimate was made.
    pub fn last_response(&self) -> Option<ResponsePayload<'_>> {
        let (_, _, p) = self.last_headers()?;
        let views = self
            .stages
            .pose
            .last_used()
            .estimator()
            .database()
            .views()
            .len();
        ResponsePayload::read(p, views, &self.buffers[2])
            .ok()
            .flatten()
    }
}

/// How [`run_source`] paces frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pacing {
    /// Frame `i` is due `i / fps` seconds after the first (a camera).
    Rate(f64),
    /// A recording's own capture times.
    Recorded,
    /// As fast as the chain goes.
    Free,
}

/// Streams up to `frames` frames (0: until the source ends) of `source`
/// through `chain`, paced by `pacing`, handing each to `observer`. Each
/// frame's trail starts when the source has made it (a camera's exposure),
/// as in the capture process; with `arm`, it carries the arm's pose of that
/// moment. Returns the frames processed.
pub fn run_source(
    chain: &mut Chain,
    source: &mut Source,
    (frames, pacing): (u64, Pacing),
    arm: Option<&crate::ros2::ArmFeed>,
    observer: &mut dyn Observe,
) -> Result<u64, RunSourceError> {
    run_frames(source, (frames, pacing), arm, |frame, rgb| {
        chain.process_observed(frame, rgb, observer).map(|_| ())
    })
}

/// [`run_source`] with `each` doing what is done with a frame (several
/// objects' chains, say).
pub fn run_frames(
    source: &mut Source,
    (frames, pacing): (u64, Pacing),
    arm: Option<&crate::ros2::ArmFeed>,
    mut each: impl FnMut(&FrameHeader, &[u8]) -> Result<(), ObserveError>,
) -> Result<u64, RunSourceError> {
    let t0 = Instant::now();
    let mut first_recorded = None;
    let mut n = 0u64;
    while frames == 0 || n < frames {
        if let Pacing::Rate(fps) = pacing
            && fps > 0.0
        {
            let due = t0 + Duration::from_secs_f64(n as f64 / fps);
            sleep_until(due);
        }
        let Some(mut p) = source.next_frame()? else {
            break;
        };
        if let (Pacing::Recorded, Some(t)) = (pacing, p.recorded_ns) {
            let first = *first_recorded.get_or_insert(t);
            sleep_until(t0 + Duration::from_nanos(t.saturating_sub(first)));
        }
        let captured = p.captured_ns.unwrap_or_else(now_ns);
        p.header.stamp_captured(captured);
        if let Some(arm) = arm {
            arm.stamp(&mut p.header, captured);
        }
        p.header.envelope_mut().trail.stages[0].published_ns = now_ns();
        each(&p.header, p.pixels.bytes())?;
        source.recycle(p.pixels);
        n += 1;
    }
    Ok(n)
}

fn sleep_until(due: Instant) {
    if let Some(wait) = due.checked_duration_since(Instant::now()) {
        std::thread::sleep(wait);
    }
}

/// Why [`run_source`] stopped early.
#[derive(Debug, thiserror::Error)]
pub enum RunSourceError {
    /// The source failed.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// An observer failed.
    #[error(transparent)]
    Observe(#[from] ObserveError),
}
