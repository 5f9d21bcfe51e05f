//! The contract every processing stage fulfils, and the one step both
//! executors take with it.
//!
//! A stage is a value with its own buffers. It reads its upstream's header
//! and payload (typed views defined beside the stage that wrote them) and
//! writes its own payload into a buffer the executor lends it: a `Vec` in
//! the in-process `Chain`, a shared-memory loan in a stage process
//! (`node`). What it returns becomes its part of the next header; a
//! [`Fault`] is counted, never dropped. The executors and the stages build
//! on this module; it knows neither.

use crate::wire::{Fault, Hop, StageId};
use acch_ipc::{Header, now_ns};
use serde::Serialize;

/// A processing stage: recognition, segmentation, pose, confidence or
/// seeding.
pub trait Stage {
    /// Which stage.
    const ID: StageId;
    /// The upstream's header it reads.
    type Input: Header + Hop;
    /// Its own part of the next header.
    type Part: From<Fault>;
    /// The header it publishes: the input's, plus its part.
    type Output: Header + Hop;

    /// Bytes of the largest payload it writes (0: header only). Shared
    /// memory is sized from it up front.
    fn max_payload(&self) -> usize;

    /// Whether it reads the frame's pixels beside its upstream's payload
    /// (recognition reads them as its payload; pose reads them to fit the
    /// object's shape to the image): a stage process then reads the frame
    /// stream too.
    const READS_FRAME: bool = false;

    /// Processes one frame: reads `input` and its `payload` (and, when it
    /// [reads the frame](Stage::READS_FRAME), the frame's packed RGB
    /// `frame`, else empty), writes its own payload into `out`
    /// (`max_payload()` bytes) and returns its part.
    fn process(
        &mut self,
        input: &Self::Input,
        payload: &[u8],
        frame: &[u8],
        out: &mut [u8],
    ) -> Result<Self::Part, Fault>;

    /// A fault the stage met on a frame it still made a part for (seeding
    /// keeps reporting the fused pose when one seed fails); counted as a
    /// returned one is.
    fn fault_in(_part: &Self::Part) -> Option<Fault> {
        None
    }

    /// The header it publishes for `input` with its `part`.
    fn output(input: &Self::Input, part: Self::Part) -> Self::Output;

    /// Where in the frame its part found the object (recognition's
    /// window) and how clearly, for a run that chooses its database set
    /// by how sharp the object is (`stages::BySet`); None: this
    /// stage finds none. Only recognition says: the other stages keep this
    /// default.
    fn object_window(_part: &Self::Part) -> Option<ObjectWindow> {
        None
    }
}

/// Where a stage's part found the object ([`Stage::object_window`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectWindow {
    /// The window in pixels.
    pub rect: crate::wire::PixelRect,
    /// Found at or above the model's threshold; false: found under it
    /// (faint), which another database set may find clearly.
    pub clear: bool,
}

/// What a stage counted over a run: where frames went and why.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StageCounters {
    /// The stage.
    pub stage: &'static str,
    /// Frames it published.
    pub processed: u64,
    /// Faults by kind ([`Fault::name`], count), only those that occurred.
    pub faults: Vec<(&'static str, u64)>,
}

impl StageCounters {
    /// Counters of stage `id`.
    pub fn new(id: StageId) -> Self {
        StageCounters {
            stage: id.name(),
            // Room for every kind: counting never allocates.
            faults: Vec::with_capacity(Fault::ALL.len()),
            ..Default::default()
        }
    }

    /// Counts one fault.
    pub fn fault(&mut self, f: Fault) {
        match self.faults.iter_mut().find(|(n, _)| *n == f.name()) {
            Some((_, n)) => *n += 1,
            None => self.faults.push((f.name(), 1)),
        }
    }

    /// How many faults of kind `f`.
    pub fn faults_of(&self, f: Fault) -> u64 {
        self.faults
            .iter()
            .find(|(n, _)| *n == f.name())
            .map_or(0, |(_, n)| *n)
    }

    /// Faults of every kind.
    pub fn total_faults(&self) -> u64 {
        self.faults.iter().map(|(_, n)| n).sum()
    }
}

/// Runs `stage` on one input received at `received_ns`: counts a fault,
/// builds the output header and stamps the stage's times in its trail
/// (published = now, as the header is handed to the transport).
pub fn step<S: Stage>(
    stage: &mut S,
    input: &S::Input,
    payload: &[u8],
    frame: &[u8],
    out: &mut [u8],
    received_ns: u64,
    counters: &mut StageCounters,
) -> S::Output {
    let part = stage
        .process(input, payload, frame, out)
        .unwrap_or_else(|f| {
            counters.fault(f);
            tracing::debug!(
                "{}: frame {}: {f}",
                S::ID.name(),
                input.envelope().frame.sequence
            );
            S::Part::from(f)
        });
    if let Some(f) = S::fault_in(&part) {
        counters.fault(f);
    }
    counters.processed += 1;
    let mut header = S::output(input, part);
    let t = &mut header.envelope_mut().trail.stages[S::ID as usize];
    t.received_ns = received_ns;
    t.published_ns = now_ns();
    header
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faults_are_counted_by_kind_without_allocating_more() {
        let mut c = StageCounters::new(StageId::Pose);
        let cap = c.faults.capacity();
        c.fault(Fault::Payload);
        c.fault(Fault::Payload);
        c.fault(Fault::Header);
        assert_eq!(c.faults_of(Fault::Payload), 2);
        assert_eq!(c.faults_of(Fault::Header), 1);
        assert_eq!(c.faults_of(Fault::Seed), 0);
        assert_eq!(c.total_faults(), 3);
        for f in Fault::ALL {
            c.fault(f);
        }
        assert_eq!(c.faults.capacity(), cap);
    }
}
