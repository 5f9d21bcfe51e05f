//! Sinks: what watches the pipeline (the rerun viewer, the MCAP recorder,
//! the zenoh publisher of results and seeds), written once for both
//! executors. In one process the chain hands each frame to its observers
//! in turn; as processes, an observer subscribes to the frame, region,
//! response and result streams like any stage, but nothing waits for it:
//! when it falls behind, iceoryx2 drops the oldest samples queued for it
//! and the gaps in sequence numbers are counted ([`Streams`]).

use crate::config::PipelineConfig;
use crate::frame::FrameHeader;
use crate::stages::{Posed, Seeded, Segmented};
use crate::streams;
use crate::wire::{Hop, StageId};
use acch_ipc::{Input, Ipc, Wake};
use std::time::Duration;

/// Why an observer failed.
#[derive(Debug, thiserror::Error)]
pub enum ObserveError {
    /// Writing the recording failed.
    #[error(transparent)]
    Record(#[from] acch_record::RecordError),
    /// The viewer failed.
    #[error(transparent)]
    Viz(#[from] acch_viz::VizError),
    /// Publishing or receiving failed.
    #[error(transparent)]
    Ipc(#[from] acch_ipc::IpcError),
    /// Publishing on ROS 2 or writing a rosbag2 bag failed.
    #[error(transparent)]
    Ros2(#[from] Ros2OutError),
    /// A result could not be written as JSON.
    #[error("writing a result as JSON")]
    Json(#[from] serde_json::Error),
    /// A file could not be written.
    #[error("{}", path.display())]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// What the system said.
        #[source]
        source: std::io::Error,
    },
}

/// Why the ROS 2 side could not start or publish.
#[derive(Debug, thiserror::Error)]
pub enum Ros2OutError {
    /// Declaring the node, a publisher or a subscriber failed.
    #[error("ROS 2")]
    Ros2(#[from] acch_ros2::node::Ros2Error),
    /// The bag could not be written.
    #[error("rosbag2 recording")]
    Bag(#[from] acch_ros2::BagError),
    /// A message could not be encoded.
    #[error("encoding a ROS 2 message")]
    Cdr(#[from] acch_ros2::CdrError),
    /// The arm's pose topic needs peers to connect to.
    #[error(
        "ros2.arm_topic needs zenoh.connect: the endpoint of the ROS 2 router or the arm's publisher"
    )]
    NoPeers,
    /// Opening the arm's session failed.
    #[error(transparent)]
    Zenoh(#[from] acch_ipc::ZenohError),
}

/// What an observer does with each sample, stream by stream. Every method
/// but [`result`](Self::result) has a default that ignores the sample.
pub trait Observe {
    /// A frame; `pixels` is empty under the copy transport (the pixels go
    /// through recognition's socket, not here).
    fn frame(&mut self, _h: &FrameHeader, _pixels: &[u8]) -> Result<(), ObserveError> {
        Ok(())
    }
    /// Segmentation's result and payload (the cropped mask leads it).
    fn region(&mut self, _h: &Segmented, _payload: &[u8]) -> Result<(), ObserveError> {
        Ok(())
    }
    /// Pose's result and payload (the response).
    fn response(&mut self, _h: &Posed, _payload: &[u8]) -> Result<(), ObserveError> {
        Ok(())
    }
    /// Before the final results of one pass; `gaps` as counted so far.
    fn results_start(&mut self, _gaps: &[Gaps; 4]) {}
    /// A final result.
    fn result(&mut self, h: &Seeded) -> Result<(), ObserveError>;
    /// After the final results of one pass.
    fn results_end(&mut self, _gaps: &[Gaps; 4]) -> Result<(), ObserveError> {
        Ok(())
    }
}

/// Observes nothing.
pub struct Nobody;

impl Observe for Nobody {
    fn result(&mut self, _: &Seeded) -> Result<(), ObserveError> {
        Ok(())
    }
}

/// Several observers, each handed every sample in turn.
pub struct Each<'a>(pub Vec<&'a mut dyn Observe>);

impl Observe for Each<'_> {
    fn frame(&mut self, h: &FrameHeader, pixels: &[u8]) -> Result<(), ObserveError> {
        self.0.iter_mut().try_for_each(|o| o.frame(h, pixels))
    }
    fn region(&mut self, h: &Segmented, payload: &[u8]) -> Result<(), ObserveError> {
        self.0.iter_mut().try_for_each(|o| o.region(h, payload))
    }
    fn response(&mut self, h: &Posed, payload: &[u8]) -> Result<(), ObserveError> {
        self.0.iter_mut().try_for_each(|o| o.response(h, payload))
    }
    fn results_start(&mut self, gaps: &[Gaps; 4]) {
        self.0.iter_mut().for_each(|o| o.results_start(gaps))
    }
    fn result(&mut self, h: &Seeded) -> Result<(), ObserveError> {
        self.0.iter_mut().try_for_each(|o| o.result(h))
    }
    fn results_end(&mut self, gaps: &[Gaps; 4]) -> Result<(), ObserveError> {
        self.0.iter_mut().try_for_each(|o| o.results_end(gaps))
    }
}

/// Counts sequence numbers missing from a stream that should see every
/// frame (each stream starts at frame 0).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Gaps {
    next: u64,
    /// Sequence numbers skipped so far.
    pub missed: u64,
}

impl Gaps {
    /// Notes that `sequence` arrived.
    pub fn see(&mut self, sequence: u64) {
        self.missed += sequence.saturating_sub(self.next);
        self.next = self.next.max(sequence + 1);
    }
}

/// The four streams an observer process reads, and the sequences each
/// missed (frames, regions, responses, results).
pub struct Streams {
    frames: Input<FrameHeader>,
    regions: Input<Segmented>,
    responses: Input<Posed>,
    results: Input<Seeded>,
    gaps: [Gaps; 4],
}

impl Streams {
    /// Subscribes to the four streams of the run of `frame_history`.
    pub fn open(ipc: &Ipc, frame_history: usize) -> Result<Self, acch_ipc::OpenError> {
        Ok(Streams {
            frames: ipc.input(streams::frames(frame_history), Wake::Never)?,
            regions: ipc.input(streams::results(StageId::Segmentation), Wake::Never)?,
            responses: ipc.input(streams::results(StageId::Pose), Wake::Never)?,
            results: ipc.input(streams::results(StageId::Seeding), Wake::Event)?,
            gaps: [Gaps::default(); 4],
        })
    }

    /// Hands every sample to `o`, in pipeline order, until a stop signal,
    /// then drains once more: everything published before the launcher
    /// stopped the observer is still queued for it. Wakes on final results
    /// (the last event of a frame); the timeout keeps frames flowing if
    /// results stop and lets the stop signal through.
    pub fn observe_until_stopped(
        &mut self,
        ipc: &Ipc,
        o: &mut dyn Observe,
    ) -> Result<(), ObserveError> {
        let ipc_err = |e: acch_ipc::IpcError| ObserveError::Ipc(e);
        let mut running = true;
        while running {
            running = ipc.keep_running();
            self.results
                .wait(Duration::from_millis(50))
                .map_err(|e| ipc_err(e.into()))?;
            while let Some(f) = self.frames.receive().map_err(|e| ipc_err(e.into()))? {
                self.gaps[0].see(f.user_header().envelope.frame.sequence);
                o.frame(f.user_header(), f.payload())?;
            }
            while let Some(m) = self.regions.receive().map_err(|e| ipc_err(e.into()))? {
                self.gaps[1].see(m.user_header().envelope().frame.sequence);
                o.region(m.user_header(), m.payload())?;
            }
            while let Some(r) = self.responses.receive().map_err(|e| ipc_err(e.into()))? {
                self.gaps[2].see(r.user_header().envelope().frame.sequence);
                o.response(r.user_header(), r.payload())?;
            }
            o.results_start(&self.gaps);
            while let Some(r) = self.results.receive().map_err(|e| ipc_err(e.into()))? {
                self.gaps[3].see(r.user_header().envelope().frame.sequence);
                o.result(r.user_header())?;
            }
            o.results_end(&self.gaps)?;
        }
        Ok(())
    }

    /// Sequences missed so far: frames, regions, responses, results.
    pub fn missed(&self) -> [u64; 4] {
        self.gaps.map(|g| g.missed)
    }
}

/// Processes beside the pipeline that watch it (`acch run --rerun`,
/// `--record`): off the hot path, they read the same streams and drop what
/// they cannot keep up with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Observer {
    /// Logs to rerun.
    Viz,
    /// Writes MCAP.
    Record,
}

impl Observer {
    /// Every observer.
    pub const ALL: [Observer; 2] = [Observer::Viz, Observer::Record];

    /// Its name on the command line (`acch stage viz`).
    pub fn name(self) -> &'static str {
        match self {
            Observer::Viz => "viz",
            Observer::Record => "record",
        }
    }

    /// Parses an observer name.
    pub fn from_name(name: &str) -> Option<Observer> {
        Self::ALL.into_iter().find(|o| o.name() == name)
    }

    /// The event id it announces readiness with (after the stages' ids).
    pub fn ready_id(self) -> usize {
        crate::wire::STAGES + self as usize
    }
}

impl PipelineConfig {
    /// The observer processes this run starts (viewer, recorder).
    pub fn observers(&self) -> Vec<Observer> {
        let mut v = Vec::new();
        if self.observers.rerun.is_some() {
            v.push(Observer::Viz);
        }
        if self.observers.record.is_some() {
            v.push(Observer::Record);
        }
        v
    }
}

/// Niceness of the observer processes: when a stage and an observer are
/// both runnable, the scheduler runs the stage (the observers still get
/// the cores' idle time, which is most of it).
pub const OBSERVER_NICE: libc::c_int = 10;

/// Lowers this process's priority to the normal scheduler at
/// [`OBSERVER_NICE`]; call before any thread starts (threads inherit it).
pub fn lower_priority(o: Observer) {
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
}
