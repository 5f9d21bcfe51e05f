//! The GStreamer source (`source = "gst:PIPELINE"`): any pipeline a robot
//! team already runs a camera with (v4l2src, a CSI element, rtspsrc, a
//! file), ended by our `videoconvert ! appsink`. Frames keep the buffer's
//! capture time on CLOCK_MONOTONIC, frames the camera or GStreamer dropped
//! are counted from the gaps in the buffers' time stamps, and a pipeline
//! that fails mid-stream (a camera unplugged) is reopened with backoff,
//! the frames lost meanwhile counted.

use crate::source_error::{CameraCounters, SourceError};
use gstreamer as gst;
use gstreamer::prelude::*;
use gstreamer_app as gst_app;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Name of the appsink this source ends every pipeline with.
const SINK: &str = "acch_sink";
/// How long a pull waits before looking at the bus and the stop flag.
const PULL_WAIT: Duration = Duration::from_millis(100);
/// How long the first frame may take (a camera's start, an RTSP connect).
const FIRST_FRAME_WAIT: Duration = Duration::from_secs(10);
/// Backoff between reopening attempts: doubles from the first to the last.
const BACKOFF: (Duration, Duration) = (Duration::from_millis(100), Duration::from_secs(2));
/// Buffers a live pipeline may queue in the appsink: one, so a slow
/// pipeline sees the newest frame and the older ones count as dropped.
const LIVE_QUEUE: u32 = 1;

/// One pulled frame: the mapped buffer (its memory is GStreamer's until
/// the frame is recycled) or a repacked copy when rows are padded.
pub struct GstPixels {
    data: GstData,
}

enum GstData {
    Mapped(gst::MappedBuffer<gst::buffer::Readable>),
    Repacked(Vec<u8>),
}

impl GstPixels {
    /// Packed RGB, `3 * width` bytes a row.
    pub fn bytes(&self) -> &[u8] {
        match &self.data {
            GstData::Mapped(m) => m.as_slice(),
            GstData::Repacked(v) => v,
        }
    }
}

/// A frame of the stream: its pixels, size and capture time.
pub struct GstFrame {
    /// Packed RGB pixels.
    pub pixels: GstPixels,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// When the buffer was captured, CLOCK_MONOTONIC ns (the pipeline
    /// clock's time of the buffer, mapped onto CLOCK_MONOTONIC).
    pub captured_ns: u64,
}

/// The caps the appsink asks for: RGB at `size` if the stream can, else
/// RGB at whatever size it gives (a second, less preferred structure), so
/// a camera picks the configured mode when it has it and a stream that
/// changes size mid-run reaches the size check instead of failing.
fn sink_caps(size: (u32, u32)) -> gst::Caps {
    let (w, h) = size;
    format!("video/x-raw,format=RGB,width={w},height={h};video/x-raw,format=RGB")
        .parse()
        .expect("static caps parse")
}

/// The full launch line of `description`.
fn launch_line(description: &str) -> String {
    let user = description.trim().trim_end_matches('!').trim_end();
    format!("{user} ! videoconvert ! appsink name={SINK}")
}

/// An open GStreamer pipeline and its appsink.
struct Running {
    pipeline: gst::Pipeline,
    sink: gst_app::AppSink,
    bus: gst::Bus,
    /// The pipeline produces frames on its own clock (a camera): frames
    /// it cannot hand over are dropped, not queued.
    live: bool,
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.pipeline.set_state(gst::State::Null);
    }
}

/// Why a pipeline stopped making frames.
enum Stop {
    /// End of stream: a file or a `num-buffers` source has ended.
    Eos,
    /// An element posted an error (or the state change failed).
    Error(String),
}

fn open(description: &str, size: (u32, u32), what: &str) -> Result<Running, SourceError> {
    let bad = |why: String| SourceError::Gst {
        pipeline: description.to_owned(),
        why,
    };
    gst::init().map_err(|e| bad(format!("GStreamer did not initialise: {e}")))?;
    let element = gst::parse::launch_full(
        &launch_line(description),
        None,
        gst::ParseFlags::FATAL_ERRORS,
    )
    .map_err(|e| bad(format!("the pipeline does not parse: {e}")))?;
    let pipeline = element
        .downcast::<gst::Pipeline>()
        .map_err(|_| bad("not a pipeline".into()))?;
    let sink = pipeline
        .by_name(SINK)
        .and_then(|e| e.downcast::<gst_app::AppSink>().ok())
        .ok_or_else(|| bad(format!("it already has an element named {SINK}")))?;
    sink.set_caps(Some(&sink_caps(size)));
    let bus = pipeline.bus().ok_or_else(|| bad("no bus".into()))?;
    let live = match pipeline.set_state(gst::State::Paused) {
        Ok(gst::StateChangeSuccess::NoPreroll) => true,
        Ok(_) => false,
        Err(_) => {
            return Err(bad(
                bus_error(&bus).unwrap_or_else(|| format!("{what} failed"))
            ));
        }
    };
    // A camera drops what the pipeline cannot take and hands a frame over
    // at once (its time stamp says when it was captured); a file waits
    // for the pipeline and is played at its frame rate.
    sink.set_drop(live);
    sink.set_sync(!live);
    sink.set_max_buffers(if live { LIVE_QUEUE } else { 2 });
    if pipeline.set_state(gst::State::Playing).is_err() {
        return Err(bad(
            bus_error(&bus).unwrap_or_else(|| format!("{what} failed"))
        ));
    }
    Ok(Running {
        pipeline,
        sink,
        bus,
        live,
    })
}

/// The first error on the bus, with the element that posted it.
fn bus_error(bus: &gst::Bus) -> Option<String> {
    while let Some(msg) = bus.pop_filtered(&[gst::MessageType::Error]) {
        if let gst::MessageView::Error(e) = msg.view() {
            return Some(error_text(&msg, e));
        }
    }
    None
}

fn error_text(msg: &gst::Message, e: &gst::message::Error) -> String {
    let from = msg
        .src()
        .map(|s| s.path_string().to_string())
        .unwrap_or_else(|| "?".into());
    match e.debug() {
        Some(d) => format!("{from}: {} ({d})", e.error()),
        None => format!("{from}: {}", e.error()),
    }
}

impl Running {
    /// The next sample, or why the pipeline stopped; `Ok(None)` while
    /// waiting (so the caller can look at its stop flag).
    fn pull(&self) -> Result<Option<gst::Sample>, Stop> {
        if let Some(s) = self
            .sink
            .try_pull_sample(gst::ClockTime::from_nseconds(PULL_WAIT.as_nanos() as u64))
        {
            return Ok(Some(s));
        }
        while let Some(msg) = self
            .bus
            .pop_filtered(&[gst::MessageType::Error, gst::MessageType::Eos])
        {
            match msg.view() {
                gst::MessageView::Error(e) => return Err(Stop::Error(error_text(&msg, e))),
                gst::MessageView::Eos(_) => return Err(Stop::Eos),
                _ => {}
            }
        }
        if self.sink.is_eos() {
            return Err(Stop::Eos);
        }
        Ok(None)
    }

    /// The CLOCK_MONOTONIC time of `buffer`'s capture: the pipeline
    /// clock's time of it (base time + running time) moved by the clock's
    /// offset from CLOCK_MONOTONIC now. A file's buffer exists when it is
    /// read (its time stamp is when it is due to be shown), so it is the
    /// time of the pull, as for a buffer without a time stamp.
    fn captured_ns(&self, buffer: &gst::BufferRef) -> u64 {
        let now = acch_ipc::now_ns();
        if !self.live {
            return now;
        }
        let (Some(pts), Some(base), Some(clock)) = (
            buffer.pts(),
            self.pipeline.base_time(),
            self.pipeline.clock(),
        ) else {
            return now;
        };
        let clock_now = clock.time().nseconds() as i128;
        let at = (base.nseconds() + pts.nseconds()) as i128;
        let mono = now as i128 - (clock_now - at);
        // A time stamp ahead of now (a clock skew) is read as now.
        mono.clamp(0, now as i128) as u64
    }
}

/// A GStreamer source, reopened when it fails.
pub struct GstSource {
    description: String,
    size: (u32, u32),
    running: Option<Running>,
    /// Time stamp and frame duration of the last frame, ns (drop counting).
    last_pts: Option<(u64, Option<u64>)>,
    /// When the last frame arrived and whether the pipeline failed since.
    last_frame_at: Option<Instant>,
    outage: bool,
    stop: Arc<AtomicBool>,
    /// What went wrong so far.
    pub counters: CameraCounters,
}

impl GstSource {
    /// Opens `description` (the part after `gst:`) for frames of `size`.
    /// A pipeline that does not parse or start is an error naming it.
    pub fn open(description: &str, size: (u32, u32)) -> Result<Self, SourceError> {
        let running = open(description, size, "starting the pipeline")?;
        Ok(GstSource {
            description: description.to_owned(),
            size,
            running: Some(running),
            last_pts: None,
            last_frame_at: None,
            outage: false,
            stop: Arc::new(AtomicBool::new(false)),
            counters: CameraCounters::default(),
        })
    }

    /// Starts `description`, waits for its first frame and returns that
    /// frame's size: RGB at `wanted` when the stream offers it, else the
    /// stream's own size.
    pub fn probe(description: &str, wanted: (u32, u32)) -> Result<(u32, u32), SourceError> {
        let running = open(description, wanted, "starting the pipeline")?;
        let t0 = Instant::now();
        loop {
            match running.pull() {
                Ok(Some(s)) => {
                    let (w, h) = sample_size(&s).ok_or_else(|| SourceError::Gst {
                        pipeline: description.to_owned(),
                        why: "its first frame has no video caps".into(),
                    })?;
                    return Ok((w, h));
                }
                Ok(None) if t0.elapsed() < FIRST_FRAME_WAIT => {}
                Ok(None) => {
                    return Err(SourceError::Gst {
                        pipeline: description.to_owned(),
                        why: format!("no frame within {} s", FIRST_FRAME_WAIT.as_secs()),
                    });
                }
                Err(Stop::Eos) => {
                    return Err(SourceError::Gst {
                        pipeline: description.to_owned(),
                        why: "the stream ended before its first frame".into(),
                    });
                }
                Err(Stop::Error(why)) => {
                    return Err(SourceError::Gst {
                        pipeline: description.to_owned(),
                        why,
                    });
                }
            }
        }
    }

    /// A flag that ends a wait for frames (and the reopening) when set.
    pub fn stop_flag(&self) -> Arc<AtomicBool> {
        self.stop.clone()
    }

    /// The next frame, whatever its size; `None` at the end of the stream
    /// or when stopped. A pipeline that fails is reopened with backoff
    /// until a frame comes again.
    pub fn next_frame(&mut self) -> Result<Option<GstFrame>, SourceError> {
        let mut backoff = BACKOFF.0;
        loop {
            if self.stop.load(Ordering::Relaxed) {
                return Ok(None);
            }
            let Some(running) = &self.running else {
                std::thread::sleep(backoff);
                backoff = (backoff * 2).min(BACKOFF.1);
                match open(&self.description, self.size, "reopening the pipeline") {
                    Ok(r) => {
                        tracing::info!("capture: gst:{} reopened", self.description);
                        self.running = Some(r);
                    }
                    Err(e) => tracing::warn!("capture: {e}; retrying in {backoff:?}"),
                }
                continue;
            };
            match running.pull() {
                Ok(Some(sample)) => {
                    if let Some(frame) = self.frame_of(&sample)? {
                        return Ok(Some(frame));
                    }
                }
                Ok(None) => {}
                Err(Stop::Eos) => {
                    tracing::info!("capture: end of stream of gst:{}", self.description);
                    return Ok(None);
                }
                Err(Stop::Error(why)) => {
                    // A camera unplugged, a network stream cut: say so,
                    // keep the rest of the pipeline running, and reopen.
                    tracing::warn!("capture: gst:{} failed: {why}; reopening", self.description);
                    self.counters.failures += 1;
                    self.running = None;
                    self.last_pts = None;
                    self.outage = true;
                }
            }
        }
    }

    /// A pulled sample as a frame, counting the frames dropped before it;
    /// `None` for a sample with no buffer.
    fn frame_of(&mut self, sample: &gst::Sample) -> Result<Option<GstFrame>, SourceError> {
        let Some(info) = sample
            .caps()
            .and_then(|c| gstreamer_video::VideoInfo::from_caps(c).ok())
        else {
            return Err(SourceError::Gst {
                pipeline: self.description.clone(),
                why: "a frame without video caps".into(),
            });
        };
        let Some(buffer) = sample.buffer_owned() else {
            return Ok(None);
        };
        let now = Instant::now();
        let frame_ns = frame_duration_ns(&info, &buffer);
        self.count_gaps(buffer.pts().map(|t| t.nseconds()), frame_ns, now);
        let Some(captured_ns) = self.running.as_ref().map(|r| r.captured_ns(&buffer)) else {
            return Ok(None);
        };
        let (width, height) = (info.width(), info.height());
        let stride = info.stride()[0] as usize;
        let row = 3 * width as usize;
        let data =
            if stride == row {
                GstData::Mapped(buffer.into_mapped_buffer_readable().map_err(|_| {
                    SourceError::Gst {
                        pipeline: self.description.clone(),
                        why: "a buffer that cannot be read".into(),
                    }
                })?)
            } else {
                // Rows padded to 4 bytes (widths not a multiple of 4): the
                // stages want packed rows.
                let map = buffer.map_readable().map_err(|_| SourceError::Gst {
                    pipeline: self.description.clone(),
                    why: "a buffer that cannot be read".into(),
                })?;
                let mut v = Vec::with_capacity(row * height as usize);
                for r in map.chunks(stride).take(height as usize) {
                    v.extend_from_slice(&r[..row]);
                }
                GstData::Repacked(v)
            };
        self.last_frame_at = Some(now);
        Ok(Some(GstFrame {
            pixels: GstPixels { data },
            width,
            height,
            captured_ns,
        }))
    }

    /// Counts the frames missing between the last frame and this one:
    /// from the time stamps' gap within a stream, from the time the
    /// pipeline was down across a reopening.
    fn count_gaps(&mut self, pts: Option<u64>, frame_ns: Option<u64>, now: Instant) {
        if self.outage {
            self.outage = false;
            if let (Some(last), Some(d)) = (self.last_frame_at, frame_ns) {
                let missed = (now.duration_since(last).as_nanos() as f64 / d as f64).round();
                self.counters.lost += (missed as u64).saturating_sub(1);
            }
        } else if let (Some((last, Some(d))), Some(p)) = (self.last_pts, pts)
            && p > last
        {
            let missed = ((p - last) as f64 / d as f64).round() as u64;
            self.counters.dropped += missed.saturating_sub(1);
        }
        self.last_pts = pts.map(|p| (p, frame_ns));
    }

    /// Whether the pipeline runs on its own clock (a camera).
    pub fn is_live(&self) -> bool {
        self.running.as_ref().is_some_and(|r| r.live)
    }
}

/// The size of a sample's video caps.
fn sample_size(s: &gst::Sample) -> Option<(u32, u32)> {
    let info = gstreamer_video::VideoInfo::from_caps(s.caps()?).ok()?;
    Some((info.width(), info.height()))
}

/// A frame's duration: from the caps' frame rate, else the buffer's own.
fn frame_duration_ns(info: &gstreamer_video::VideoInfo, buffer: &gst::Buffer) -> Option<u64> {
    let fps = info.fps();
    if fps.numer() > 0 && fps.denom() > 0 {
        Some(1_000_000_000 * fps.denom() as u64 / fps.numer() as u64)
    } else {
        buffer.duration().map(|d| d.nseconds()).filter(|&d| d > 0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_launch_line_ends_with_our_sink_whatever_the_user_ended_with() {
        assert_eq!(
            launch_line("videotestsrc ! videoconvert ! "),
            "videotestsrc ! videoconvert ! videoconvert ! appsink name=acch_sink"
        );
    }

    #[test]
    fn a_pipeline_that_does_not_parse_is_named() {
        let Err(e) = GstSource::open("videotestsrc ! no_such_element_here", (64, 48)) else {
            panic!("opened");
        };
        let s = e.to_string();
        assert!(s.contains("no_such_element_here"), "{s}");
    }

    #[test]
    fn drops_are_counted_from_time_stamp_gaps() {
        let mut s = GstSource {
            description: String::new(),
            size: (1, 1),
            running: None,
            last_pts: None,
            last_frame_at: None,
            outage: false,
            stop: Default::default(),
            counters: CameraCounters::default(),
        };
        let d = 33_333_333;
        let now = Instant::now();
        for pts in [0, d, 2 * d, 5 * d, 6 * d, 10 * d] {
            s.count_gaps(Some(pts), Some(d), now);
        }
        // 2 -> 5 misses two, 6 -> 10 misses three.
        assert_eq!(s.counters.dropped, 5);
        // Across a reopening, the frames of the time it was down are lost
        // (the time stamps start again).
        s.outage = true;
        s.last_frame_at = Some(now);
        s.count_gaps(Some(0), Some(d), now + Duration::from_millis(500));
        assert_eq!(s.counters.lost, 14);
        assert_eq!(s.counters.dropped, 5);
    }
}
