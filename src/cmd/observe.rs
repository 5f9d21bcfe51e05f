//! What the observer processes (`viz`, `record`) share. They subscribe to
//! the frames and to the segmentation (mask), pose (response) and seeding
//! (final result) services like any stage, but nothing waits for them. When
//! one falls behind, iceoryx2 drops the oldest samples queued for it; the
//! gaps in sequence numbers are counted.

use acch_ipc::{FrameHeader, Input, Ipc, Observer, ResultMsg, StageId};
use anyhow::{Result, anyhow};
use iceoryx2::prelude::EventId;
use std::time::Duration;

/// What an observer does with each sample, stream by stream.
pub(crate) trait Observe {
    /// A frame; `pixels` is empty under the copy transport (the pixels go
    /// through the stages' sockets, not here).
    fn frame(&mut self, h: &FrameHeader, pixels: &[u8]) -> Result<()>;
    /// Segmentation's result (the cropped mask leads its payload).
    fn mask(&mut self, h: &ResultMsg, payload: &[u8]) -> Result<()>;
    /// Pose's result (the response leads its payload).
    fn response(&mut self, h: &ResultMsg, payload: &[u8]) -> Result<()>;
    /// Before the final results of one pass; `gaps` as counted so far.
    fn results_start(&mut self, _gaps: &[Gaps; 4]) {}
    /// A final result.
    fn result(&mut self, h: &ResultMsg) -> Result<()>;
    /// After the final results of one pass.
    fn results_end(&mut self, _gaps: &[Gaps; 4]) -> Result<()> {
        Ok(())
    }
}

/// The four streams an observer reads, and the sequences each missed
/// (frames, masks, responses, results).
pub(crate) struct Streams {
    frames: Input<FrameHeader>,
    masks: Input<ResultMsg>,
    responses: Input<ResultMsg>,
    results: Input<ResultMsg>,
    gaps: [Gaps; 4],
}

impl Streams {
    /// Subscribes to the four streams.
    pub(crate) fn open(ipc: &Ipc) -> Result<Self> {
        Ok(Streams {
            frames: ipc.frame_input(false)?,
            masks: ipc.result_input(StageId::Segmentation)?,
            responses: ipc.result_input(StageId::Pose)?,
            results: ipc.result_input(StageId::Seeding)?,
            gaps: [Gaps::default(); 4],
        })
    }

    /// Hands every sample to `o`, in pipeline order, until a stop signal,
    /// then drains once more: everything published before the launcher
    /// stopped the observer is still queued for it. Wakes on final results
    /// (the last event of a frame); the timeout keeps frames flowing if
    /// results stop and lets the stop signal through.
    pub(crate) fn observe_until_stopped(&mut self, ipc: &Ipc, o: &mut impl Observe) -> Result<()> {
        let mut running = true;
        while running {
            running = ipc.keep_running();
            self.results.wait(Duration::from_millis(50))?;
            while let Some(f) = self.frames.receive()? {
                self.gaps[0].see(f.user_header().sequence);
                o.frame(f.user_header(), f.payload())?;
            }
            while let Some(m) = self.masks.receive()? {
                self.gaps[1].see(m.user_header().sequence);
                o.mask(m.user_header(), m.payload())?;
            }
            while let Some(r) = self.responses.receive()? {
                self.gaps[2].see(r.user_header().sequence);
                o.response(r.user_header(), r.payload())?;
            }
            o.results_start(&self.gaps);
            while let Some(r) = self.results.receive()? {
                self.gaps[3].see(r.user_header().sequence);
                o.result(r.user_header())?;
            }
            o.results_end(&self.gaps)?;
        }
        Ok(())
    }

    /// Sequences missed so far: frames, masks, responses, results.
    pub(crate) fn missed(&self) -> [u64; 4] {
        self.gaps.map(|g| g.missed)
    }
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
pub(crate) fn response_values(b: &[u8]) -> Vec<f32> {
    b.chunks_exact(4)
        .map(|c| f32::from_ne_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
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
pub(crate) fn announce_ready(ipc: &Ipc, o: Observer) -> Result<()> {
    ipc.control_notifier("ready")?
        .notify_with_custom_event_id(EventId::new(o.ready_id()))
        .map_err(|e| anyhow!("{} announcing readiness: {e:?}", o.name()))?;
    Ok(())
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
        assert_eq!(response_values(&b), v);
    }
}
